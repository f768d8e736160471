"""A world file's images: where an ``image`` key may point, how large an image may be, and its
pixels as terrain labels.

- Path: ``image`` is a path relative to the world file's folder that resolves (symlinks
  followed) to a regular file inside that folder; an absolute path, a ``..`` escape or a
  symlink out of the folder is refused naming the key, before the file is opened. The file is
  opened by its resolved path without following a symlink again and read whole (at most
  :data:`ird_core.worlds.file_values.MAX_IMAGE_BYTES`), so what is decoded is what was checked.
- Size: Pillow's ``Image.open`` reads only the header; the width and height are checked against
  :data:`~ird_core.worlds.file_values.MAX_MAP_SIDE` and
  :data:`~ird_core.worlds.file_values.MAX_MAP_VALUES` cells before any pixel is decoded.
- Formats: PNG, and PGM/PPM (Pillow's ``PPM`` reader); any mode Pillow converts to RGB.

Errors are ``ValueError`` ``"<file>: <key>: <problem>, got <value>"`` (``<key>`` e.g.
``training_worlds[0].image``, ``<value>`` the path as written).
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, UnidentifiedImageError

from ird_core.worlds.file_values import (MAX_IMAGE_BYTES, MAX_MAP_SIDE, MAX_MAP_VALUES, FileErrors,
                                         read_colour)
from ird_core.worlds.safe_yaml import read_capped

__all__ = ["IMAGE_FORMATS", "image_path", "read_image"]

IMAGE_FORMATS: tuple[str, ...] = ("PNG", "PPM")


def image_path(ctx: FileErrors, folder: Path, value: Any, key: str) -> Path:
    """The resolved path of ``image`` value ``value``: inside ``folder`` (see the module docstring)."""
    if not isinstance(value, str) or not value.strip() or "\x00" in value:
        raise ctx.fail(key, "must be an image file name", value)
    if Path(value).is_absolute():
        raise ctx.fail(key, "must be a path relative to the world file's folder (absolute paths are refused)", value)
    try:
        root = folder.resolve()
        target = (folder / value).resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop
        raise ctx.fail(key, f"cannot be resolved ({exc})", value) from None
    if not target.is_relative_to(root):
        raise ctx.fail(key, f"must stay inside the world file's folder {root} (it resolves to {target})", value)
    return target


def _check_size(ctx: FileErrors, key: str, value: str, size: tuple[int, int]) -> None:
    width, height = size
    if not (1 <= width <= MAX_MAP_SIDE and 1 <= height <= MAX_MAP_SIDE and width * height <= MAX_MAP_VALUES):
        raise ctx.fail(key, f"{value} is {width}x{height} (W x H) pixels; a map has 1 to {MAX_MAP_SIDE} cells per "
                       f"side", value)


def _decode(ctx: FileErrors, data: bytes, key: str, value: str) -> np.ndarray:
    """The image's pixels as an (H, W, 3) int64 array, top row first; its size checked before decoding."""
    try:
        with warnings.catch_warnings():
            # the size check below refuses far smaller images than Pillow's bomb warning
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data), formats=IMAGE_FORMATS)  # reads the header only
    except Image.DecompressionBombError as exc:
        raise ctx.fail(key, f"{value} is far larger than a map may be ({MAX_MAP_SIDE} cells per side): {exc}",
                       value) from None
    except UnidentifiedImageError:
        raise ctx.fail(key, f"{value} is not a PNG, PGM or PPM image", value) from None
    except Exception as exc:  # noqa: BLE001 - any decoder failure is an unreadable image
        raise ctx.fail(key, f"cannot read the image ({exc})", value) from None
    with image:
        _check_size(ctx, key, value, image.size)
        try:
            return np.asarray(image.convert("RGB"), dtype=np.int64)
        except Exception as exc:  # noqa: BLE001 - a truncated or corrupt image body
            raise ctx.fail(key, f"cannot decode the image ({exc})", value) from None


def read_image(ctx: FileErrors, folder: Path, value: Any, key: str, legend: list[dict], labels: list[int]
               ) -> np.ndarray:
    """Image file -> (H, W) int8 labels, row 0 = the image's bottom row; every pixel a legend colour."""
    path = image_path(ctx, folder, value, key)
    rgb = _decode(ctx, read_capped(ctx, path, key, value, MAX_IMAGE_BYTES, follow_symlinks=False), key, value)
    codes = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
    legend_codes = np.array([(c[0] << 16) | (c[1] << 8) | c[2]
                             for c in (read_colour(ctx, e["colour"], "") for e in legend)])
    order = np.argsort(legend_codes)
    pos = np.clip(np.searchsorted(legend_codes[order], codes), 0, len(order) - 1)
    known = legend_codes[order][pos] == codes
    if not known.all():
        top_row, col = np.argwhere(~known)[0]
        bad = tuple(int(v) for v in rgb[top_row, col])
        raise ctx.fail(key, f"{value}: pixel (row {rgb.shape[0] - 1 - top_row}, col {col}) has colour {list(bad)}, "
                       "which is not in the terrains legend", value)
    return np.asarray(labels, dtype=np.int8)[order][pos][::-1].copy()
