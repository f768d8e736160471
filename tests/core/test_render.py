"""Mission figures: the PNG is written at the stated size, in the style's colours (ird_core.style), row 0 at
the bottom; risk maps on the scale they are given."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

from ird_core import render, style
from ird_core.worlds.terrain import TERRAIN_COLORS, TEST_MAP, TRAIN_MAP, Terrain, sample_terrain


def colour_present(image: np.ndarray, colour: str, tolerance: float = 2.5 / 255) -> bool:
    rgb = np.array(to_rgb(colour))
    return bool(np.any(np.all(np.abs(image[..., :3] - rgb) <= tolerance, axis=-1)))


def pixel_rows_of(image: np.ndarray, colour: str, tolerance: float = 2.5 / 255) -> np.ndarray:
    rgb = np.array(to_rgb(colour))
    return np.nonzero(np.all(np.abs(image[..., :3] - rgb) <= tolerance, axis=-1))[0]


@pytest.fixture(scope="module")
def maps() -> tuple[np.ndarray, np.ndarray]:
    return sample_terrain(TRAIN_MAP, 0), sample_terrain(TEST_MAP, 0)


@pytest.mark.parametrize("with_risk", [False, True])
def test_mission_png_has_size_and_terrain_colours(tmp_path: Path, maps: tuple, with_risk: bool) -> None:
    train, test = maps
    path = tmp_path / "mission.png"
    cells = [(2, 2), (3, 2), (3, 3), (4, 3)]
    risk = np.linspace(0, 100, test.size).reshape(test.shape) if with_risk else None
    render.save_mission_figure(path, train, test, {"literal": cells, "ird": cells[:2]},
                               risk_map=risk, title="test", train_start=(2, 2), test_start=(2, 2))
    assert path.exists() and path.stat().st_size > 0
    image = mpimg.imread(path)
    width, height = render.mission_figure_size(with_risk)
    assert image.shape[:2] == (height, width)
    for k in (Terrain.DIRT, Terrain.GRASS, Terrain.TARGET, Terrain.LAVA):
        assert colour_present(image, TERRAIN_COLORS[k]), k
    assert colour_present(image, style.LITERAL_COLOR) and colour_present(image, style.IRD_COLOR)  # by planner name
    # The risk panel adds pixels of its colour map's dark end only when a risk map is given.
    assert colour_present(image, style.RISK_STOPS[-1], tolerance=6 / 255) == with_risk


def test_row_zero_is_drawn_at_the_bottom(tmp_path: Path) -> None:
    labels = np.zeros((6, 6), dtype=np.int8)
    labels[0, :] = Terrain.LAVA  # bottom row
    labels[5, :] = Terrain.TARGET  # top row
    path = tmp_path / "rows.png"
    render.save_mission_figure(path, labels, labels, {}, title="rows")
    image = mpimg.imread(path)
    lava_rows = pixel_rows_of(image, TERRAIN_COLORS[Terrain.LAVA])
    target_rows = pixel_rows_of(image, TERRAIN_COLORS[Terrain.TARGET])
    dirt_rows = pixel_rows_of(image, TERRAIN_COLORS[Terrain.DIRT])
    # Image rows grow downwards; legend swatches are excluded by taking the medians of the
    # map cells (each map row is many pixels tall, swatches a few).
    assert np.median(lava_rows) > np.median(dirt_rows) > np.median(target_rows)


def test_draw_functions_on_a_user_axes() -> None:
    figure = Figure(figsize=(3, 3), dpi=50)
    FigureCanvasAgg(figure)
    ax = figure.subplots()
    labels = sample_terrain(TEST_MAP, 1)
    render.draw_terrain(ax, labels, start=(0, 0))
    render.draw_path(ax, [(0, 0), (0, 1)], "p", "#000000")
    assert len(ax.images) == 1
    assert any(line.get_label() == "p" for line in ax.get_lines())
    figure.canvas.draw()


def test_draw_risk_keeps_the_scale_it_is_given() -> None:
    figure = Figure(figsize=(3, 3), dpi=50)
    FigureCanvasAgg(figure)
    ax = figure.subplots()
    image = render.draw_risk(ax, np.full((3, 3), 0.5), vmin=0.0, vmax=2.0, colorbar=False)
    assert image.get_clim() == (0.0, 2.0) and image.norm(0.5) == pytest.approx(0.25)
    with pytest.raises(ValueError, match="risk_map"):
        render.draw_risk(ax, np.full((3, 3), -1.0))
    with pytest.raises(ValueError, match="scale"):
        render.draw_risk(ax, np.zeros((3, 3)), vmin=1.0, vmax=1.0)


def test_outcome_is_read_off_the_map() -> None:
    labels = np.zeros((3, 3), dtype=np.int64)
    labels[0, 1], labels[0, 2] = Terrain.LAVA, Terrain.TARGET
    assert render.path_outcome(labels, [(0, 0), (0, 1), (0, 2)]) == "lava, target"
    assert render.path_outcome(labels, [(0, 0)]) == "no lava, no target"
    labels[2, 2] = Terrain.GOLD
    assert render.path_outcome(labels, [(0, 0), (1, 2), (2, 2)]) == "no lava, no target, gold"


def test_render_errors(tmp_path: Path, maps: tuple) -> None:
    train, test = maps
    with pytest.raises(ValueError, match="risk_map"):
        render.save_mission_figure(tmp_path / "x.png", train, test, {}, risk_map=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="risk_map"):
        render.save_mission_figure(tmp_path / "x.png", train, test, {}, risk_map=np.full(test.shape, 150.0))
    with pytest.raises(ValueError, match="labels"):
        render.save_mission_figure(tmp_path / "x.png", train.astype(float), test, {})
    with pytest.raises(ValueError, match="start"):
        render.save_mission_figure(tmp_path / "x.png", train, test, {}, test_start=(99, 0))
    with pytest.raises(ValueError, match="cells"):
        render.save_mission_figure(tmp_path / "x.png", train, test, {"bad": [1, 2, 3]})
