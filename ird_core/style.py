"""The project's one picture style: every colour a picture, the live view or the web page draws.

One module owns them, so a colour means the same thing everywhere (core figures, the demo's
``mission.png`` and ``rounds.png``, the bag plots, the live view, the designer's web page):

- terrains (:data:`TERRAIN_COLOR_BY_NAME`, by name; :data:`ird_core.worlds.terrain.TERRAIN_COLORS`
  is the same list in ``Terrain`` label order). World images are drawn and read in these colours,
  so they never change: dirt brown, grass green, target yellow, lava red, gold orange;
- plans and planners (:func:`planner_color`): the literal plan magenta, IRD blue (a second IRD
  variant light blue), the oracle grey, Rob's driven trail cyan;
- options of a question: by index while the question is open (:func:`option_color`: the web page's
  A, B, ...), by role once it is answered (the chosen option solid :data:`CHOSEN_OPTION_COLOR`,
  the others dashed :data:`OTHER_OPTION_COLOR`);
- paths sharing a colour (two ``literal`` missions) are told apart by :func:`path_dashes` and a
  small offset, never by a second colour;
- the risk colour map (:data:`RISK_STOPS`): pale yellow (no spread) to dark red (the scale's
  top), one map for matplotlib (:func:`risk_cmap`), numpy (:func:`risk_rgb`, the live view) and
  the web page (:func:`web_colors_js`, written to ``ird_ros/web/static/colors.js`` by
  ``scripts/gen_web_style.py``). Risk maps of one picture share one scale (:func:`shared_risk_limits`).

Invariants: every colour is ``"#rrggbb"`` in lower case; the terrain colours, the plan colours
(literal, IRD, IRD variant, oracle, Rob) and the option colours are pairwise distinct;
:func:`planner_color` is total and deterministic (an unknown planner gets a fallback colour from
its name, never an error); the risk stops get darker from first to last (relative luminance
strictly decreasing), so more risk is darker also in greyscale. No ROS, and matplotlib is
imported only by :func:`risk_cmap`.
"""

from __future__ import annotations

import json
import zlib
from typing import Any

import numpy as np

__all__ = [
    "TERRAIN_COLOR_BY_NAME", "UNKNOWN_COLOR", "LITERAL_COLOR", "IRD_COLOR", "IRD_ALT_COLOR", "ORACLE_COLOR",
    "ROB_COLOR", "INK", "PAPER", "NEUTRAL", "OPTION_COLORS", "CHOSEN_OPTION_COLOR", "OTHER_OPTION_COLOR",
    "BASELINE_COLORS", "FALLBACK_COLORS", "RISK_STOPS", "PATH_DASHES", "START_MARKER",
    "hex_rgb", "luminance", "halo_color", "terrain_color", "planner_color", "option_color", "baseline_color",
    "path_dashes", "shared_risk_limits", "risk_rgb", "risk_cmap", "web_style", "web_colors_js",
]

#: Terrain colours by name (dirt brown, grass green, target yellow, lava red, gold orange).
TERRAIN_COLOR_BY_NAME: dict[str, str] = {
    "dirt": "#8b5a2b", "grass": "#3c9a3c", "target": "#ffd400", "lava": "#e0201b", "gold": "#ff8c00",
}
#: A cell whose terrain is unknown (or a terrain name outside the set above).
UNKNOWN_COLOR = "#b0b0b0"
#: The literal (proxy) plan and planner.
LITERAL_COLOR = "#ff00ff"
#: The IRD plan and the main IRD planner.
IRD_COLOR = "#1f3fff"
#: A second IRD variant beside the main one (Sample-Z next to MaxEnt-Z, random next to info-gain queries).
IRD_ALT_COLOR = "#7fb2ff"
#: The oracle (true-reward optimum).
ORACLE_COLOR = "#6e6e6e"
#: Rob's driven trail (live view).
ROB_COLOR = "#00c8ff"
#: Lines, text, edges.
INK = "#000000"
#: Background, halos on dark lines, the start marker's face.
PAPER = "#ffffff"
#: Zero lines, frames, grid lines.
NEUTRAL = "#999999"
#: Options of an open question, by index (A, B, C, D, then again).
OPTION_COLORS: tuple[str, ...] = ("#000000", "#8a2be2", "#ffffff", "#00a0a0")
#: An answered question: the chosen option (solid) and the others (dashed).
CHOSEN_OPTION_COLOR = "#ffffff"
OTHER_OPTION_COLOR = "#000000"
#: The factorial's reward baselines.
BASELINE_COLORS: dict[str, str] = {"initial_state": "#8172b2", "training_features": "#4c72b0", "log_z": "#ccb974"}
#: Planners or baselines the style does not name, chosen by a hash of the name.
FALLBACK_COLORS: tuple[str, ...] = ("#17becf", "#8c564b", "#bcbd22", "#9467bd", "#2ca02c", "#d62728")
#: The risk colour map's stops, evenly spaced over [0, 1] (ColorBrewer YlOrRd, 9 classes).
RISK_STOPS: tuple[str, ...] = ("#ffffcc", "#ffeda0", "#fed976", "#feb24c", "#fd8d3c", "#fc4e2a", "#e31a1c",
                               "#bd0026", "#800026")
#: Line styles (matplotlib dash specs) of paths that share a colour, by their index among them.
PATH_DASHES: tuple[Any, ...] = ("solid", (0, (5, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))
#: The start cell's marker: a white disc with a black rim (matplotlib keywords).
START_MARKER: dict[str, Any] = {"marker": "o", "markersize": 9, "markerfacecolor": PAPER, "markeredgecolor": INK}

_PLANNERS: dict[str, str] = {
    "literal": LITERAL_COLOR, "oracle": ORACLE_COLOR, "ird": IRD_COLOR, "ird_maxent_z": IRD_COLOR,
    "ird_sample_z": IRD_ALT_COLOR, "info_gain": IRD_COLOR, "random": IRD_ALT_COLOR,
}


def hex_rgb(color: str) -> tuple[float, float, float]:
    """``"#rrggbb"`` -> (r, g, b) in [0, 1]."""
    text = color.lstrip("#")
    if len(text) != 6 or any(ch not in "0123456789abcdefABCDEF" for ch in text):
        raise ValueError(f"colour: expected #rrggbb, got {color!r}")
    return tuple(int(text[i:i + 2], 16) / 255.0 for i in (0, 2, 4))  # type: ignore[return-value]


def luminance(color: str) -> float:
    """Relative luminance (WCAG 2) of ``"#rrggbb"``, 0 (black) .. 1 (white)."""
    lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in hex_rgb(color)]
    return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]


def halo_color(color: str) -> str:
    """The outline that keeps a line of ``color`` visible on any terrain: paper for dark lines, ink for light."""
    return INK if luminance(color) > 0.5 else PAPER


def terrain_color(name: str) -> str:
    """A terrain's colour by name; :data:`UNKNOWN_COLOR` for a name the style does not know."""
    return TERRAIN_COLOR_BY_NAME.get(str(name), UNKNOWN_COLOR)


def _fallback(name: str) -> str:
    return FALLBACK_COLORS[zlib.crc32(name.encode("utf-8")) % len(FALLBACK_COLORS)]


def planner_color(name: str) -> str:
    """The colour of a planner, strategy or plan label.

    Exact names first (``literal``, ``oracle``, ``ird_maxent_z``, ``ird_sample_z``, ``info_gain``,
    ``random``), then by prefix, case-insensitive: a label starting with ``literal`` is literal,
    with ``ird`` IRD (``"IRD per_step"``, ``"ird_after_2"``), with ``oracle`` the oracle; anything
    else a fallback colour fixed by its name (same name, same colour, across runs).
    """
    key = str(name).strip().lower()
    if key in _PLANNERS:
        return _PLANNERS[key]
    for prefix in ("literal", "oracle", "ird"):
        if key.startswith(prefix):
            return _PLANNERS[prefix]
    return _fallback(key)


def option_color(index: int) -> str:
    """Option ``index`` (0 = A) of an open question."""
    return OPTION_COLORS[int(index) % len(OPTION_COLORS)]


def baseline_color(name: str) -> str:
    """A reward baseline's colour (the factorial); a fallback fixed by the name for another one."""
    return BASELINE_COLORS.get(str(name), _fallback(str(name)))


def path_dashes(index: int) -> Any:
    """The dash style of the ``index``-th path among paths of one colour (0: solid)."""
    return PATH_DASHES[int(index) % len(PATH_DASHES)]


def shared_risk_limits(*maps: "np.ndarray | None") -> tuple[float, float]:
    """(vmin, vmax) of one colour scale for every risk map of a picture: 0 and the largest finite
    value over all maps (1.0 when there is none or all are 0), so equal values get equal colours
    in every panel and a map half as risky looks half as dark."""
    top = 0.0
    for m in maps:
        if m is None:
            continue
        values = np.asarray(m, dtype=np.float64)
        values = values[np.isfinite(values)]
        if values.size:
            top = max(top, float(values.max()))
    return 0.0, top if top > 0 else 1.0


def risk_rgb(fraction: "np.ndarray | float") -> np.ndarray:
    """Colours of the risk map for ``fraction`` of the scale (0..1, clipped; NaN counts as 0):
    ``(..., 3)`` uint8, linear between :data:`RISK_STOPS` (what :func:`risk_cmap` and the web page do)."""
    f = np.nan_to_num(np.clip(np.asarray(fraction, dtype=np.float64), 0.0, 1.0))
    stops = np.array([hex_rgb(c) for c in RISK_STOPS])  # (S, 3)
    grid = np.linspace(0.0, 1.0, len(RISK_STOPS))
    rgb = np.stack([np.interp(f, grid, stops[:, k]) for k in range(3)], axis=-1)
    return np.round(255.0 * rgb).astype(np.uint8)


def risk_cmap() -> Any:
    """The risk colour map for matplotlib (256 levels between :data:`RISK_STOPS`)."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("ird_risk", list(RISK_STOPS), N=256)


def web_style() -> dict[str, Any]:
    """Every colour the web page uses, as JSON types (written to ``colors.js``)."""
    return {
        "terrains": dict(TERRAIN_COLOR_BY_NAME), "unknown": UNKNOWN_COLOR, "literal": LITERAL_COLOR,
        "ird": IRD_COLOR, "oracle": ORACLE_COLOR, "rob": ROB_COLOR, "ink": INK, "paper": PAPER,
        "neutral": NEUTRAL, "options": list(OPTION_COLORS), "chosen_option": CHOSEN_OPTION_COLOR,
        "other_option": OTHER_OPTION_COLOR, "risk_stops": list(RISK_STOPS),
    }


def web_colors_js() -> str:
    """The text of ``ird_ros/web/static/colors.js``: ``IRD_STYLE``, the :func:`web_style` dict."""
    body = json.dumps(web_style(), indent=2, sort_keys=True)
    return ("// Generated by scripts/gen_web_style.py from ird_core/style.py: do not edit by hand.\n"
            "// The colours of every picture of the project (terrains, plans, options, risk map).\n"
            "\"use strict\";\n"
            f"const IRD_STYLE = Object.freeze({body});\n")
