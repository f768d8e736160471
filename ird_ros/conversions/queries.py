"""numpy <-> ROS messages of the designer conversation (ProposeQuery, AnswerQuery, QueryRecord).

Part of :mod:`ird_ros.conversions` (use ``conv.X``); docs/spec.md section 7. Decoding a
QueryRecord is :func:`ird_ros.bags.rounds.event_from_msg` (ROS-free, shared with the bag
analysis); the event is an ``ird_core.vocabulary.QueryEvent``.
"""

from __future__ import annotations

import array
from typing import Any, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import Path

from ird_core.vocabulary import QueryEvent, QueryKind, QueryStrategy, parse
from ird_msgs.msg import QueryRecord
from ird_ros.bags.rounds import QueryRecordData, event_from_msg
from ird_ros.conversions.grids import MAP_FRAME, _as_float_array, _check_finite, _check_names, _f, make_header
from ird_ros.conversions.paths import cells_to_path

__all__ = ["options_to_paths", "query_record_to_msg", "query_record_from_msg"]


def options_to_paths(
    option_cells: Sequence[np.ndarray],
    *,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    height: int | None = None,
    width: int | None = None,
    stamp: Time | None = None,
) -> list[Path]:
    """One nav_msgs/Path per option ((T+1, 2) cells each), poses at cell centres."""
    return [cells_to_path(cells, resolution=resolution, origin=origin, height=height, width=width, stamp=stamp)
            for cells in option_cells]


def query_record_to_msg(
    *,
    query_id: int,
    event: QueryEvent | str,
    strategy: QueryStrategy | str,
    options: Sequence[Path],
    feature_names: Sequence[str],
    option_features: np.ndarray,
    information_gain: float,
    chosen: int = -1,
    beta: float = 0.0,
    answered_by: str = "",
    num_answers: int = 0,
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
    kind: QueryKind | str = QueryKind.PATHS,
    option_proxies: np.ndarray | None = None,
) -> QueryRecord:
    """A QueryRecord; ``option_features`` (q, d) with q = ``len(options)``, d = ``len(feature_names)``;
    ``kind`` "" = "paths"; ``option_proxies`` (q, p) the offered proxies of a "proxies" query (``None``
    or empty for "paths")."""
    field = "QueryRecord"
    query_kind = parse(QueryKind, kind or QueryKind.PATHS, f"{field}.kind")
    proxies = np.zeros((0,)) if option_proxies is None else _as_float_array(f"{field}.option_proxies",
                                                                            option_proxies, np.float64)
    if proxies.size and (proxies.ndim != 2 or proxies.shape[0] != len(options)):
        raise _f(f"{field}.option_proxies", f"expected shape ({len(options)}, p), got {proxies.shape}")
    _check_finite(f"{field}.option_proxies", proxies)
    event_kind = parse(QueryEvent, event, f"{field}.event")
    parse(QueryStrategy, strategy, f"{field}.strategy")
    names = _check_names(f"{field}.feature_names", feature_names)
    feats = _as_float_array(f"{field}.option_features", option_features, np.float64)
    if feats.shape != (len(options), len(names)):
        raise _f(f"{field}.option_features", f"expected shape ({len(options)}, {len(names)}), got {feats.shape}")
    _check_finite(f"{field}.option_features", feats)
    if event_kind is not QueryEvent.PROPOSED and not 0 <= int(chosen) < len(options):
        raise _f(f"{field}.chosen", f"{chosen} is out of range for {len(options)} options")
    msg = QueryRecord()
    msg.header = make_header(stamp, frame_id)
    msg.query_id = int(query_id)
    msg.event = event_kind.value
    msg.strategy = QueryStrategy(strategy).value
    msg.kind = query_kind.value
    msg.option_proxies = array.array("d", np.ascontiguousarray(proxies).tobytes())
    msg.options = list(options)
    msg.feature_names = list(names)
    msg.option_features = array.array("d", np.ascontiguousarray(feats).tobytes())
    msg.information_gain = float(information_gain)
    msg.chosen = int(chosen) if event_kind is not QueryEvent.PROPOSED else -1
    msg.beta = float(beta)
    msg.answered_by = str(answered_by)
    msg.num_answers = int(num_answers)
    return msg


def query_record_from_msg(msg: Any, *, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0),
                          field: str = "QueryRecord") -> QueryRecordData:
    """Decode a QueryRecord (see :func:`ird_ros.bags.rounds.event_from_msg`)."""
    return event_from_msg(msg, resolution=resolution, origin=origin, field=field)
