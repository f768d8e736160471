"""Analysis of the stack's rosbag2 (MCAP) bags without ROS: ``analyze(bag, out_dir)`` is the whole
analysis behind ``scripts/analyze_bag.py``: the per-topic summary, Rob's missions with their
outcomes, per-label statistics, the designer's question rounds and (with ``out_dir``) PNG plots.

The work is done by the modules it composes (import their names from them):
:mod:`ird_ros.bags.storage` (the ``rosbags`` typestore, decoded messages, per-topic summary),
:mod:`ird_ros.bags.missions` (mission segmentation and the small decoders, no rosbags),
:mod:`ird_ros.bags.rounds` (question rounds) and :mod:`ird_ros.bags.plots` (the matplotlib plots).
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any, Callable

from rosbags.typesys.store import Typestore

from ird_ros.bags.missions import (
    MISSION_TOPICS,
    Mission,
    Terrain,
    label_statistics,
    latest_before,
    missions_from_messages,
    terrain_from_msg,
)
from ird_ros.bags.plots import plot_posterior, plot_query_rounds, plot_returns, plot_trajectories
from ird_ros.bags.rounds import Round, event_from_msg, round_summary, rounds_from_events
from ird_ros.bags.storage import BagMessage, TopicSummary, make_typestore, read_messages, summarize
from ird_ros.graph import names

__all__ = ["extract_missions", "extract_query_rounds", "analyze"]

#: Feature maps the posterior plot reads the terrains' mean features from, in order of preference.
_POSTERIOR_MAPS = (names.TOPIC_HYPOTHESIS_TEST_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES)


def extract_missions(bag: str | Path, messages: dict[str, list[BagMessage]] | None = None) -> list[Mission]:
    """The missions of a bag (see :mod:`ird_ros.bags.missions` for how they are segmented).

    ``messages``, if given, are the bag's already decoded messages (``read_messages``).
    """
    if messages is None:
        messages = read_messages(bag, MISSION_TOPICS)
    return missions_from_messages(messages)


def extract_query_rounds(messages: dict[str, list[BagMessage]]) -> tuple[list[Round], Terrain | None]:
    """The rounds of /ird/queries (poses mapped to cells on the latest /world/terrain's grid) and
    that terrain (None without one: a 1 m grid at the origin)."""
    terrains = messages.get(names.TOPIC_TERRAIN, [])
    records = messages.get(names.TOPIC_QUERIES, [])
    terrain = terrain_from_msg(terrains[-1].msg) if terrains else None
    res, origin = (terrain.resolution, terrain.origin) if terrain is not None else (1.0, (0.0, 0.0))
    return rounds_from_events(event_from_msg(r.msg, resolution=res, origin=origin) for r in records), terrain


def analyze(bag: str | Path, out_dir: str | Path | None = None, typestore: Typestore | None = None) -> dict[str, Any]:
    """Summary, missions, the designer's rounds (``query_rounds``: :func:`round_summary` rows) and
    (with ``out_dir``) PNG plots of a bag, as a JSON-able dict.

    Plots: ``trajectories_<i>.png`` (one per distinct terrain the missions ran on; without
    any /world/terrain just the paths; none for a bag without missions), ``true_return.png``, ``posterior.png`` (latest
    /ird/posterior, per terrain of the latest /world/terrain on the feature map with its layers)
    and ``query_rounds.png`` (each question's options on the map), each only
    when the bag holds what it needs. A plot that fails to draw does not stop the others or the
    report: ``plot_errors`` lists ``"<file>: <Type>: <text>"`` for each (the bag was read; the fault
    is the plotting's).
    """
    bag = Path(bag)
    store = typestore or make_typestore()
    topics = summarize(bag)
    messages = read_messages(bag, [*MISSION_TOPICS, names.TOPIC_TERRAIN, names.TOPIC_POSTERIOR,
                                   names.TOPIC_QUERIES, *_POSTERIOR_MAPS], store)
    missions = missions_from_messages(messages)
    rounds, rounds_terrain = extract_query_rounds(messages)
    firsts = [t.first_ns for t in topics if t.first_ns is not None]
    lasts = [t.last_ns for t in topics if t.last_ns is not None]
    start_ns = min(firsts) if firsts else 0
    end_ns = max(lasts) if lasts else 0
    plots: list[str] = []
    plot_errors: list[str] = []
    if out_dir is not None:
        plots, plot_errors = _write_plots(Path(out_dir), messages, missions, rounds, rounds_terrain, start_ns)
    return {
        "bag": str(bag),
        "start_ns": start_ns,
        "end_ns": end_ns,
        "duration_s": (end_ns - start_ns) / 1e9,
        "topics": [_topic_row(t, start_ns) for t in topics],
        "missions": [_mission_row(m, start_ns) for m in missions],
        "labels": label_statistics(missions),
        "query_rounds": [round_summary(r, start_ns) for r in rounds],
        "plots": plots,
        "plot_errors": plot_errors,
    }


def _write_plots(out: Path, messages: dict[str, list[BagMessage]], missions: list[Mission], rounds: list[Round],
                 rounds_terrain: Terrain | None, start_ns: int) -> tuple[list[str], list[str]]:
    """The PNG plots of :func:`analyze` in ``out``: their paths, and what failed to draw."""
    out.mkdir(parents=True, exist_ok=True)
    written: list[str] = []
    errors: list[str] = []

    def draw(name: str, plot: Callable[[Path], Path]) -> None:
        """``plot(out / name)``: its path into ``written``, or its failure into ``errors``."""
        try:
            written.append(str(plot(out / name)))
        except Exception as exc:  # noqa: BLE001 - a plotting bug: reported, the other plots still drawn
            errors.append(f"{name}: {type(exc).__name__}: {exc}")

    terrains = messages.get(names.TOPIC_TERRAIN, [])
    groups: dict[int, list[Mission]] = defaultdict(list)
    for m in missions:
        tidx = latest_before(terrains, m.start_ns)
        groups[-1 if tidx is None else tidx].append(m)
    for n, (tidx, ms) in enumerate(sorted(groups.items())):
        terrain = terrain_from_msg(terrains[tidx].msg) if tidx >= 0 else None
        title = f"Rob's trajectories on terrain #{tidx}" if tidx >= 0 else "Rob's trajectories"
        draw(f"trajectories_{n}.png", lambda path, ms=ms, terrain=terrain, title=title:
             plot_trajectories(ms, terrain, path, title))
    if any(len(m.status_returns) for m in missions):
        draw("true_return.png", lambda path: plot_returns(missions, start_ns, path))
    if messages.get(names.TOPIC_POSTERIOR):
        post = messages[names.TOPIC_POSTERIOR][-1].msg
        terrain = terrain_from_msg(terrains[-1].msg) if terrains else None
        draw("posterior.png", lambda path: plot_posterior(post, path, terrain, _posterior_map(messages, post)))
    if rounds:
        draw("query_rounds.png", lambda path: plot_query_rounds(rounds, rounds_terrain, path))
    return written, errors


def _posterior_map(messages: dict[str, list[BagMessage]], post: Any) -> Any:
    """The latest feature map (test features first) whose layers are the posterior's features, or None."""
    for topic in _POSTERIOR_MAPS:
        for record in reversed(messages.get(topic, [])):
            if tuple(record.msg.layers) == tuple(post.feature_names):
                return record.msg
    return None


def _topic_row(t: TopicSummary, start_ns: int) -> dict[str, Any]:
    """A topic of the summary as a JSON-able row (times in s since ``start_ns``)."""
    return {
        "topic": t.topic,
        "type": t.msgtype,
        "count": t.count,
        "first_s": None if t.first_ns is None else (t.first_ns - start_ns) / 1e9,
        "last_s": None if t.last_ns is None else (t.last_ns - start_ns) / 1e9,
        "rate_hz": t.rate_hz,
        "durability": t.durability,
    }


def _mission_row(m: Mission, start_ns: int) -> dict[str, Any]:
    """A mission as a JSON-able row (its start in s since ``start_ns``)."""
    return {
        "index": m.index,
        "label": m.label,
        "mode": m.mode,
        "baseline": m.baseline,
        "objective": m.objective,
        "start_s": (m.start_ns - start_ns) / 1e9,
        "plan_moves": m.plan_moves,
        "plan_length_m": m.plan_length_m,
        "executed_length_m": m.executed_length_m,
        "executed_moves": m.executed_moves,
        "steps": m.steps,
        "horizon": m.horizon,
        "done": m.done,
        "stopped": m.stopped,
        "end": m.end,
        "outcome": m.outcome,
        "touched_lava": m.touched_lava,
        "reached_target": m.reached_target,
        "true_return": m.true_return,
    }
