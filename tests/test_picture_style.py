"""One picture style (ird_core.style) for every picture, the live view and the web page.

Proves: no colour literal outside the style module in the plotting modules and the web page's
script (AST / text scan, itself checked on a snippet full of literals); the committed
``colors.js`` is the generated one; the style's own invariants; risk maps of one picture on one
scale; a 50-d posterior drawn per terrain; no gold in a picture of a world without gold; paths
sharing a colour told apart; legends outside the maps; visible 0% bars; the IRD end marker
visible when Rob stays at the start.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path
from types import SimpleNamespace

import matplotlib.colors as mcolors
import numpy as np
import pytest
from matplotlib import colormaps

from ird_core import render, style
from ird_core.experiments import report
from ird_core.worlds.terrain import TERRAIN_COLORS, TERRAIN_NAMES, Terrain
from ird_ros.apps import demo_rounds as dr
from ird_ros.bags import plots
from ird_ros.bags.missions import Mission
from ird_ros.bags.missions import Terrain as BagTerrain
from ird_ros.viz.scene import risk_layer

ROOT = Path(__file__).resolve().parents[1]
PLOTTING = ("ird_core/render.py", "ird_core/experiments/report.py", "ird_core/experiments/active_report.py",
            "ird_core/experiments/posterior_terrain.py", "ird_ros/bags/plots.py", "ird_ros/bags/analysis.py",
            "ird_ros/viz/scene.py", "ird_ros/apps/demo_rounds.py", "ird_ros/apps/demo.py")
STATIC = ROOT / "ird_ros" / "web" / "static"
COLOUR_KEYWORDS = {"color", "colour", "c", "fc", "ec", "facecolor", "edgecolor", "markerfacecolor",
                   "markeredgecolor", "mfc", "mec", "ecolor", "foreground", "colors", "background", "cmap"}
HEX = re.compile(r"#[0-9a-fA-F]{3}(?:[0-9a-fA-F]{3})?(?:[0-9a-fA-F]{2})?")
FMT = re.compile(r"[-.:,ov^<>1-4spP*hH+xXdD|_]*[bgrcmykw][-.:,ov^<>1-4spP*hH+xXdD|_]*")


def colour_literals(source: str) -> list[str]:
    """Colour literals in Python ``source``: hex strings and ``tab:``/``xkcd:``/``C<n>`` names
    anywhere, colour names or colour-map names given to a colour keyword (or ``colormaps[...]``,
    ``get_cmap(...)``), and matplotlib format strings with a colour letter (``"k--"``)."""
    found: dict[int, str] = {}  # id of the literal's node -> its text (each literal once)
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            text = node.value.strip()
            if HEX.fullmatch(text) or text.startswith(("tab:", "xkcd:")) or re.fullmatch(r"C\d", text):
                found[id(node)] = text
        elif isinstance(node, ast.keyword) and node.arg in COLOUR_KEYWORDS:
            for sub in ast.walk(node.value):
                if isinstance(sub, ast.Constant) and isinstance(sub.value, str) and sub.value != "none" and (
                        mcolors.is_color_like(sub.value) or sub.value in colormaps):
                    found[id(sub)] = sub.value
        elif isinstance(node, ast.Call):
            name = getattr(node.func, "attr", getattr(node.func, "id", ""))
            for arg in node.args:
                if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
                    continue
                if (name == "get_cmap" and arg.value in colormaps) or (
                        name in ("plot", "step", "errorbar") and FMT.fullmatch(arg.value)):
                    found[id(arg)] = arg.value
        elif (isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant)
              and isinstance(node.slice.value, str)
              and getattr(node.value, "id", getattr(node.value, "attr", "")) == "colormaps"):
            found[id(node.slice)] = node.slice.value
    return list(found.values())


def test_the_scanner_finds_every_kind_of_colour_literal() -> None:
    snippet = ('ax.plot(x, y, "k--", color="magenta")\nax.imshow(a, cmap="inferno")\nC = "#1f77b4"\n'
               'ax.bar(x, h, color="tab:blue", ecolor="0.6")\nm = colormaps["viridis"]\n'
               'ax.plot(x, y, "o", color=style.INK, label="gold")\n')
    assert sorted(colour_literals(snippet)) == sorted(["k--", "magenta", "inferno", "#1f77b4", "tab:blue", "0.6",
                                                       "viridis"])


@pytest.mark.parametrize("module", PLOTTING)
def test_no_colour_literal_outside_the_style_module(module: str) -> None:
    assert colour_literals((ROOT / module).read_text(encoding="utf-8")) == []


def test_the_web_page_takes_every_colour_from_the_generated_style() -> None:
    assert (STATIC / "colors.js").read_text(encoding="utf-8") == style.web_colors_js()
    app = (STATIC / "app.js").read_text(encoding="utf-8")
    assert not HEX.search(app.replace('"#rrggbb"', ""))
    assert not re.search(r"rgba?\(\s*\d", app)
    strings = re.findall(r'"([^"\\]*)"|\'([^\'\\]*)\'', app)
    assert [s for pair in strings for s in pair if s and s != "none" and mcolors.is_color_like(s)] == []
    bar = re.search(r"\.scale \.bar \{[^}]*\}", (STATIC / "style.css").read_text(encoding="utf-8"))
    assert bar is not None and "gradient" not in bar.group(0)
    page = (STATIC / "index.html").read_text(encoding="utf-8")
    assert page.index("/static/colors.js") < page.index("/static/app.js")


def test_style_invariants() -> None:
    assert TERRAIN_COLORS == tuple(style.TERRAIN_COLOR_BY_NAME[n] for n in TERRAIN_NAMES)
    plans = [style.LITERAL_COLOR, style.IRD_COLOR, style.IRD_ALT_COLOR, style.ORACLE_COLOR, style.ROB_COLOR]
    every = list(style.TERRAIN_COLOR_BY_NAME.values()) + plans + list(style.OPTION_COLORS)
    assert len(set(every)) == len(every)
    assert all(re.fullmatch(r"#[0-9a-f]{6}", c) for c in every + list(style.RISK_STOPS))
    # every name gets a colour; plan labels of the demo and the bags map to the planners'
    assert style.planner_color("IRD per_step") == style.planner_color("ird_per_step") == style.IRD_COLOR
    assert style.planner_color("literal (proxy)") == style.LITERAL_COLOR
    assert style.planner_color("cvar_0.1") == style.planner_color("cvar_0.1") in style.FALLBACK_COLORS
    lum = [style.luminance(c) for c in style.RISK_STOPS]
    assert all(a > b for a, b in zip(lum, lum[1:]))  # more risk is darker, in greyscale too


def test_risk_colours_agree_in_matplotlib_numpy_and_the_live_view() -> None:
    t = np.linspace(0, 1, 11)
    cmap = np.round(255 * style.risk_cmap()(t)[:, :3])
    assert np.abs(cmap - style.risk_rgb(t)).max() <= 2  # 256 levels vs exact interpolation
    costs = np.array([[0, 50, 100]], dtype=np.int8)
    layer = risk_layer(costs, resolution=1.0, origin=(0.0, 0.0), stamp_ns=1)
    rgb = np.stack([layer.field_array(k) for k in ("red", "green", "blue")], axis=-1)[0]
    assert rgb.tolist() == style.risk_rgb(np.array([0.0, 0.5, 1.0])).tolist()


def _outcome(label: str, cells) -> dr.Outcome:
    return dr.Outcome(label, [tuple(map(int, c)) for c in cells], 0.0, False, True, 1.0, False)


def _rounds_figure(labels: np.ndarray, risks: list[np.ndarray]):
    paths = [np.array([[0, 0], [0, 1], [1, 1]]), np.array([[0, 0], [1, 0], [1, 1]])]
    counts = dr.terrain_counts(labels, paths)
    rounds = [dr.RoundResult(i + 1, i + 1, 0.3, tuple(paths), 0, "simulated", _outcome("p", paths[0]), counts, r)
              for i, r in enumerate(risks[1:])]
    return dr.rounds_figure(labels, (0, 0), _outcome("literal", paths[0]), _outcome("IRD", paths[1]), risks[0],
                            rounds, "t")


def test_risk_panels_of_one_picture_share_one_scale() -> None:
    labels = np.zeros((4, 5), dtype=np.int64)
    risk = np.random.default_rng(0).uniform(0.1, 1.0, labels.shape)
    fig = _rounds_figure(labels, [risk, risk, 2 * risk])
    panels = [im for ax in fig.axes for im in ax.images if im.get_cmap().name == "ird_risk"]
    assert len(panels) == 3
    assert {im.get_clim() for im in panels} == {(0.0, float((2 * risk).max()))}
    # the 1x panel is half as dark as the 2x one: its top is half way up the scale, not at its end
    assert panels[1].norm(risk.max()) == pytest.approx(0.5)
    bar = [ax for ax in fig.axes if ax.get_ylabel().startswith("reward spread")]
    assert len(bar) == 1 and "one scale" in bar[0].get_ylabel()


def _fake_posterior(d: int, rng: np.random.Generator):
    samples = rng.normal(size=(30, d))
    return SimpleNamespace(feature_names=[f"obs_{k}" for k in range(d)], samples=samples.ravel(),
                           proxy_weights=rng.normal(size=d), method="maxent_z", beta=10.0, num_samples=30,
                           r_hat_max=1.01)


def test_a_50d_posterior_is_drawn_per_terrain() -> None:
    rng = np.random.default_rng(1)
    msg = _fake_posterior(50, rng)
    classes = rng.integers(0, 4, (6, 7)).astype(np.uint8)  # dirt, grass, target, lava; no gold cell
    terrain = BagTerrain(classes, tuple(TERRAIN_NAMES), 1.0, (0.0, 0.0))
    grid = SimpleNamespace(info=SimpleNamespace(height=6, width=7), layers=msg.feature_names,
                           data=rng.normal(size=6 * 7 * 50))
    fig = plots.posterior_figure(msg, terrain, grid)
    (ax,) = fig.axes
    assert [t.get_text() for t in ax.get_xticklabels()] == ["dirt", "grass", "target", "lava"]
    rewards = plots.terrain_rewards(np.reshape(msg.samples, (30, 50)), np.reshape(grid.data, (6, 7, 50)), classes,
                                    TERRAIN_NAMES)
    assert list(rewards) == ["dirt", "grass", "target", "lava"] and all(r.shape == (30,) for r in rewards.values())
    assert fig.get_size_inches()[0] < 8
    # without a feature map: one row per feature, the figure grows in height, not in width
    fig = plots.posterior_figure(msg)
    assert len(fig.axes[0].get_yticklabels()) == 50 and fig.get_size_inches()[0] == 7.0


def _legend_texts(fig) -> list[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return [t.get_text() for leg in legends for t in leg.get_texts()]


def test_gold_only_in_pictures_of_worlds_with_gold() -> None:
    labels = np.zeros((5, 5), dtype=np.int64)
    labels[2, 2], labels[4, 4] = Terrain.LAVA, Terrain.TARGET
    path = {"literal": [(0, 0), (0, 1)], "IRD": [(0, 0)]}
    for gold in (False, True):
        test = labels.copy()
        if gold:
            test[3, 3] = Terrain.GOLD
        mission = render.mission_figure(labels, test, path, test_start=(0, 0))
        rounds = _rounds_figure(test, [np.ones(test.shape)])
        bag = plots.trajectories_figure([], BagTerrain(test.astype(np.uint8), tuple(TERRAIN_NAMES), 1.0, (0, 0)))
        for fig in (mission, rounds, bag):
            texts = _legend_texts(fig) + [ax.get_title() for ax in fig.axes]
            assert any("gold" in t for t in texts) == gold, texts


def test_paths_sharing_a_colour_stay_apart() -> None:
    cells = [(0, 0), (0, 1), (1, 1)]
    fig = render.mission_figure(np.zeros((3, 3), np.int64), np.zeros((3, 3), np.int64),
                                {"literal": cells, "literal again": cells})
    lines = [ln for ln in fig.axes[1].get_lines() if ln.get_label().startswith("literal")]
    assert lines[0].get_color() == lines[1].get_color() == style.LITERAL_COLOR
    assert lines[0].get_linestyle() != lines[1].get_linestyle()
    assert not np.allclose(lines[0].get_xydata(), lines[1].get_xydata())
    xy = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5]])
    missions = [Mission(k, "literal", 0, 1, plan_xy=xy, touched_lava=False, true_return=1.0) for k in range(2)]
    fig = plots.trajectories_figure(missions, None)
    drawn = [ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("#")]
    assert len(drawn) == 2 and drawn[0].get_linestyle() != drawn[1].get_linestyle()
    assert not np.allclose(drawn[0].get_xydata(), drawn[1].get_xydata())


def test_legends_lie_outside_the_maps() -> None:
    rng = np.random.default_rng(2)
    labels = rng.integers(0, 4, (8, 8))
    mission = render.mission_figure(labels, labels, {"literal": [(0, 0), (0, 1)], "IRD": [(0, 0), (1, 0)]},
                                    rng.uniform(0, 100, (8, 8)), train_start=(0, 0), test_start=(0, 0))
    terrain = BagTerrain(labels.astype(np.uint8), tuple(TERRAIN_NAMES), 0.5, (0.0, 0.0))
    xy = np.array([[0.25, 0.25], [0.75, 0.25]])
    bag = plots.trajectories_figure([Mission(0, "literal", 0, 1, plan_xy=xy, true_return=0.0)], terrain)
    for fig in (mission, bag):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
        assert legends
        maps = [ax.get_window_extent(renderer) for ax in fig.axes if ax.images]
        for legend in legends:
            box = legend.get_window_extent(renderer)
            assert not any(box.overlaps(m) for m in maps)


def test_ird_end_marker_is_visible_when_rob_stays_at_the_start(tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    labels = np.zeros((6, 6), dtype=np.int64)
    path = tmp_path / "m.png"
    render.save_mission_figure(path, labels, labels, {"literal": [(2, 2), (2, 3), (3, 3)], "IRD": [(2, 2)] * 4},
                               test_start=(2, 2))
    fig = render.mission_figure(labels, labels, {"literal": [(2, 2), (2, 3), (3, 3)], "IRD": [(2, 2)] * 4},
                                test_start=(2, 2))
    fig.canvas.draw()
    box = fig.axes[1].get_window_extent()  # the test map only: the legend lies outside it
    image = mpimg.imread(path)[..., :3]
    height = image.shape[0]
    crop = image[int(height - box.y1):int(height - box.y0), int(box.x0):int(box.x1)]
    ird = np.array(style.hex_rgb(style.IRD_COLOR))
    assert np.all(np.abs(crop - ird) <= 3 / 255, axis=-1).sum() > 20
    texts = _legend_texts(fig)
    assert any(t.startswith("IRD: no lava") for t in texts) and any(t.startswith("literal:") for t in texts)


def test_zero_bars_are_marked() -> None:
    summaries = report.read_results_csv(ROOT / "docs" / "results" / "results.csv")
    main = [s for s in summaries if s.experiment == "main"]
    figures = report.figure4_figures(summaries)
    lava = figures["figure4_lava.png"].axes[0]
    zero_labels = [t for t in lava.texts if t.get_text() == "0%"]
    assert len(zero_labels) == sum(s.lava_fraction == 0 for s in main) > 0
