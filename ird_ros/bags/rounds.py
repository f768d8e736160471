"""The conversation with the designer as data: ``/ird/queries`` events, rounds, open queries.

ROS-free (numpy only): it reads any object with the fields of ``ird_msgs/msg/QueryRecord``
(an rclpy message, a message decoded from a bag by ``rosbags``, or a test's stand-in), so the
designer node, the bag analysis and the tests share one decoder.

- :func:`event_from_msg`: one QueryRecord -> :class:`QueryRecordData` (validated; option paths as
  (T+1, 2) cell arrays; the query's ``kind`` and, for "proxies", the offered proxy weights. A record
  of an older bag without ``kind`` / ``option_proxies`` is a "paths" query).
- :func:`rounds_from_events`: events in arrival order -> :class:`Round` per proposal (with its
  answer, if any). A query id is unique for the inference node's lifetime; a repeated
  ``proposed`` id (the inference node restarted) starts a new round.
- :func:`open_queries`: proposals still without an answer (what a respawned designer answers).
- :func:`round_summary` / :func:`rounds_table`: the JSON rows and the text table of
  ``scripts/analyze_bag.py``.
- :func:`option_returns`: the true return of each option on the ground-truth terrain (what the
  simulated designer judges by).
- :func:`record_dict`: the JSON dict of an event for the web page.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field as dataclass_field
from typing import Any, Iterable, Sequence

import numpy as np

from ird_core.vocabulary import QueryEvent, QueryKind, QueryStrategy, parse
from ird_core.worlds.evaluation import evaluate_path
from ird_ros.geometry import point_cells
from ird_ros.jobs.ground_truth import evaluation_terrain
from ird_ros.stamps import stamp_ns

__all__ = [
    "QueryRecordData",
    "Round",
    "event_from_msg",
    "rounds_from_events",
    "open_queries",
    "round_summary",
    "rounds_table",
    "option_returns",
    "record_dict",
]

@dataclass(frozen=True)
class QueryRecordData:
    """One ``/ird/queries`` record (a QueryRecord as numpy).

    Attributes:
        query_id: the query's id.
        event: proposed or answered.
        strategy: how the question was picked.
        options: q arrays of shape (T+1, 2), int64 (row, col) cells of each option's path.
        feature_names: the d feature names.
        option_features: (q, d) float64 feature counts.
        information_gain: nats.
        chosen: the chosen option, -1 while unanswered.
        beta: rationality of the answer (0 while unanswered).
        answered_by: who answered ("" while unanswered).
        num_answers: answers in the evidence after this event.
        stamp_ns: header stamp in ns.
        kind: "paths" (options are paths on the query map) or "proxies" (options are proxy rewards,
            each drawn as its plan on the TRAINING map).
        option_proxies: (q, p) float64 offered proxy weights for "proxies"; (q, 0) for "paths".
    """

    query_id: int
    event: QueryEvent
    strategy: QueryStrategy
    options: tuple[np.ndarray, ...]
    feature_names: tuple[str, ...]
    option_features: np.ndarray
    information_gain: float
    chosen: int
    beta: float
    answered_by: str
    num_answers: int
    stamp_ns: int
    kind: QueryKind = QueryKind.PATHS
    option_proxies: np.ndarray = dataclass_field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def num_options(self) -> int:
        return len(self.options)


@dataclass(frozen=True)
class Round:
    """A proposal and its answer (``answer`` is None while the query is open)."""

    proposal: QueryRecordData
    answer: QueryRecordData | None

    @property
    def query_id(self) -> int:
        return self.proposal.query_id

    @property
    def chosen(self) -> int | None:
        return None if self.answer is None else self.answer.chosen


def _err(field: str, problem: str) -> ValueError:
    return ValueError(f"{field}: {problem}")


def event_from_msg(msg: Any, *, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0),
                   field: str = "QueryRecord") -> QueryRecordData:
    """Decode a QueryRecord; poses are mapped to cells with the map's ``resolution`` and ``origin``
    (for a "proxies" record, pass the TRAINING map's: its options are plans on that map).

    ``kind`` "" or missing (an older bag) is "paths"; ``option_proxies`` must be empty for "paths"
    and hold q*p finite values (p >= 1) for "proxies".

    Raises:
        ValueError: naming the field (``QueryRecord.option_features: ...``).
    """
    event = parse(QueryEvent, str(msg.event), f"{field}.event")
    strategy = parse(QueryStrategy, str(msg.strategy), f"{field}.strategy")
    names = tuple(str(n) for n in msg.feature_names)
    if not names:
        raise _err(f"{field}.feature_names", "must not be empty")
    options = tuple(
        point_cells(np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses], dtype=np.float64)
                    .reshape(-1, 2), resolution, (float(origin[0]), float(origin[1]))).astype(np.int64)
        for path in msg.options)
    q, d = len(options), len(names)
    if q < 2:
        raise _err(f"{field}.options", f"expected >= 2 options, got {q}")
    if any(len(o) == 0 for o in options):
        raise _err(f"{field}.options", "every option needs at least one pose")
    features = np.asarray(msg.option_features, dtype=np.float64).reshape(-1)
    if features.size != q * d:
        raise _err(f"{field}.option_features", f"expected q*d = {q}*{d} = {q * d} values, got {features.size}")
    if not np.all(np.isfinite(features)):
        raise _err(f"{field}.option_features", "non-finite value(s)")
    kind = parse(QueryKind, str(getattr(msg, "kind", "")) or QueryKind.PATHS.value, f"{field}.kind")
    proxies = _option_proxies(np.asarray(getattr(msg, "option_proxies", ()), dtype=np.float64).reshape(-1), kind, q,
                              f"{field}.option_proxies")
    chosen = int(msg.chosen)
    answered = event is QueryEvent.ANSWERED
    if answered and not 0 <= chosen < q:
        raise _err(f"{field}.chosen", f"{chosen} is out of range for {q} options")
    return QueryRecordData(
        query_id=int(msg.query_id), event=event, strategy=strategy, options=options,
        feature_names=names, option_features=features.reshape(q, d),
        information_gain=float(msg.information_gain), chosen=chosen if answered else -1,
        beta=float(msg.beta), answered_by=str(msg.answered_by), num_answers=int(msg.num_answers),
        stamp_ns=stamp_ns(msg.header.stamp), kind=kind, option_proxies=proxies)


def _option_proxies(flat: np.ndarray, kind: QueryKind, q: int, field: str) -> np.ndarray:
    """The (q, p) proxy weights of a record (checked against its kind); (q, 0) for "paths"."""
    if kind is QueryKind.PATHS:
        if flat.size:
            raise _err(field, f"a paths query offers no proxies, got {flat.size} value(s)")
        return np.zeros((q, 0))
    if flat.size == 0 or flat.size % q:
        raise _err(field, f"expected q*p values (q = {q} options, p >= 1 proxy features), got {flat.size}")
    if not np.all(np.isfinite(flat)):
        raise _err(field, "non-finite value(s)")
    return flat.reshape(q, -1)


def rounds_from_events(events: Iterable[QueryRecordData]) -> list[Round]:
    """One :class:`Round` per ``proposed`` event, in proposal order, each with its first answer.

    An answer pairs with the latest proposal of its id that has no answer yet; an answer with no
    such proposal (its proposal fell out of the history) is ignored.
    """
    rounds: list[Round] = []
    latest: dict[int, int] = {}  # query id -> index in rounds of its latest proposal
    for ev in events:
        if ev.event is QueryEvent.PROPOSED:
            latest[ev.query_id] = len(rounds)
            rounds.append(Round(ev, None))
        elif ev.query_id in latest and rounds[latest[ev.query_id]].answer is None:
            i = latest[ev.query_id]
            rounds[i] = Round(rounds[i].proposal, ev)
    return rounds


def open_queries(events: Iterable[QueryRecordData]) -> list[QueryRecordData]:
    """The proposals (in order) that have no answer yet."""
    return [r.proposal for r in rounds_from_events(events) if r.answer is None]


def round_summary(r: Round, start_ns: int = 0) -> dict[str, Any]:
    """A round as a JSON-able row (times in s since ``start_ns``; answer fields None while open)."""
    p, a = r.proposal, r.answer
    return {
        "query_id": p.query_id,
        "kind": p.kind.value,
        "strategy": p.strategy.value,
        "information_gain": _finite_or_none(p.information_gain),
        "num_options": p.num_options,
        "horizon": int(len(p.options[0]) - 1),
        "proposed_s": (p.stamp_ns - start_ns) / 1e9,
        "chosen": None if a is None else a.chosen,
        "answered_by": None if a is None else (a.answered_by or "client"),
        "beta": None if a is None else a.beta,
        "num_answers": None if a is None else a.num_answers,
        "answered_s": None if a is None else (a.stamp_ns - start_ns) / 1e9,
    }


def rounds_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width text table of :func:`round_summary` rows: query id, strategy, info gain,
    options, answer ("open" while unanswered), who answered, answers in the evidence after it."""
    head = f"{'query':>5}  {'strategy':<9}  {'info gain':>9}  {'options':>7}  {'answer':>6}  {'by':<10}  {'answers':>7}"
    lines = [head]
    for row in rows:
        gain = "-" if row["information_gain"] is None else f"{row['information_gain']:.4f}"
        answer = "open" if row["chosen"] is None else str(row["chosen"])
        count = "" if row["num_answers"] is None else str(row["num_answers"])
        lines.append(f"{row['query_id']:>5}  {row['strategy']:<9}  {gain:>9}  {row['num_options']:>7}  "
                     f"{answer:>6}  {row['answered_by'] or '':<10}  {count:>7}")
    return "\n".join(lines)


def option_returns(classes: np.ndarray, class_names: Sequence[str], terrain_names: Sequence[str],
                   terrain_rewards: Sequence[float], options: Sequence[np.ndarray]) -> np.ndarray:
    """True return of each option: ``ird_core.worlds.evaluation.evaluate_path`` on the ground truth.

    Args:
        classes: (H, W) class indices into ``class_names`` (255 = unknown), e.g. /world/terrain.
        class_names: the terrain classes' names.
        terrain_names, terrain_rewards: the ground-truth reward per terrain name (/world/proxy).
        options: q (T+1, 2) (row, col) cell arrays.
    Returns:
        (q,) float64; as ``ird_core.worlds.lavaland.true_return`` (every cell counts, start included).
    Raises:
        ValueError: naming the field (a class without a reward, an unknown cell, a cell off the map):
            an option over unknown terrain is never judged.
    """
    table = dict(zip(terrain_names, (float(r) for r in terrain_rewards)))
    if len(table) != len(terrain_rewards) or len(terrain_names) != len(terrain_rewards):
        raise _err("terrain_rewards", f"{len(terrain_rewards)} rewards for {len(terrain_names)} terrain names")
    labels, reward = evaluation_terrain(classes, class_names, table, unrewarded_unknown=True)
    h, w = labels.shape
    returns = np.empty(len(options))
    for k, cells in enumerate(options):  # q is small; each path is evaluated vectorised
        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        if np.any(cells < 0) or np.any(cells[:, 0] >= h) or np.any(cells[:, 1] >= w):
            raise _err(f"options[{k}]", f"a cell lies off the {h}x{w} terrain")
        outcome = evaluate_path(labels, cells, reward)
        if outcome.unknown_cells:
            raise _err(f"options[{k}]", "a cell's terrain is unknown or has no true reward")
        returns[k] = outcome.true_return
    return returns


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def record_dict(ev: QueryRecordData) -> dict[str, Any]:
    """The JSON-able dict of an event (the page's ``show_query``/``show_answer``, :mod:`ird_ros.web.server`);
    ``option_proxies`` q lists of p weights ("proxies"), q empty lists ("paths")."""
    return {
        "query_id": ev.query_id,
        "event": ev.event.value,
        "strategy": ev.strategy.value,
        "kind": ev.kind.value,
        "options": [o.tolist() for o in ev.options],
        "option_proxies": ev.option_proxies.tolist(),
        "feature_names": list(ev.feature_names),
        "option_features": ev.option_features.tolist(),
        "information_gain": _finite_or_none(ev.information_gain),
        "chosen": ev.chosen,
        "beta": ev.beta,
        "answered_by": ev.answered_by,
        "num_answers": ev.num_answers,
        "stamp": ev.stamp_ns / 1e9,
    }
