"""What the designer page shows, and what a click may change (ROS-free; used by ``ird_ros.web.server``).

``PageState`` holds the world (the test map), the training map (``train_world``: where a
proxies query's options are drawn), the queries of this world, the answers being sent, the posterior,
the risk map and whether the graph has finished; ``snapshot()`` is the JSON the page renders.
``refusal`` says why a click must not be sent. Options are named by letters everywhere the page
shows text (``option_letter``: A, B, C, ...; index 0 is A).
"""

from __future__ import annotations

from typing import Any

__all__ = ["PageState", "option_letter", "thank_you"]


def option_letter(index: int) -> str:
    """``A`` for option 0, ``B`` for 1, ...; the number itself outside A..Z."""
    return chr(ord("A") + index) if 0 <= index < 26 else str(index)


def thank_you(query_id: int, chosen: int) -> str:
    """The page's line after an accepted answer: the option's letter and the question, nothing
    about the sampler (its statistics are in the node's log and on the posterior card)."""
    return f"Thank you: Option {option_letter(chosen)} recorded for question #{query_id}; Rob's beliefs are updated."


class PageState:
    """What the page shows; every method is called with the WebDesigner's lock held."""

    def __init__(self) -> None:
        self.version = 0
        self.world: dict[str, Any] | None = None
        self.train_world: dict[str, Any] | None = None  # the training map (proxies queries)
        self.queries: dict[int, dict[str, Any]] = {}  # query_id -> latest record, this world
        self.stale: set[int] = set()  # ids of earlier worlds' queries
        self.pending: set[int] = set()  # ids whose answer is being sent from this page
        self.accepted: dict[int, int] = {}  # id -> option accepted from this page
        self.posterior: dict[str, Any] | None = None
        self.risk_map: dict[str, Any] | None = None
        self.finished: str | None = None  # why the graph ended (the page stops asking), else None
        self.mission: dict[str, Any] | None = None  # how the last drive ended (WebDesigner.show_mission)

    def history(self) -> list[dict[str, Any]]:
        answered = [r for r in self.queries.values() if r.get("chosen", -1) >= 0]
        return sorted(answered, key=lambda r: r["query_id"])

    def open_query(self) -> dict[str, Any] | None:
        """The newest query not answered (nor accepted from this page); none once finished."""
        if self.finished is not None:
            return None
        open_ids = [q for q, r in self.queries.items() if r.get("chosen", -1) < 0 and q not in self.accepted]
        return self.queries[max(open_ids)] if open_ids else None

    def snapshot(self) -> dict[str, Any]:
        return {
            "version": self.version,
            "world": self.world,
            "train_world": self.train_world,
            "query": self.open_query(),
            "pending": sorted(self.pending),
            "history": self.history(),
            "posterior": self.posterior,
            "risk_map": self.risk_map,
            "finished": self.finished,
            "mission": self.mission,
        }

    def refusal(self, query_id: int, chosen: int) -> str | None:
        """Why the click ``(query_id, chosen)`` must not be sent, or None if it may."""
        if self.finished is not None:
            return f"finished: {self.finished}; no answer can be sent any more"
        if query_id in self.stale:
            return f"query_id: query {query_id} belongs to an earlier world; it can no longer be answered"
        record = self.queries.get(query_id)
        if record is None:
            return f"query_id: unknown query {query_id} (no such question was asked on this page)"
        if record.get("chosen", -1) >= 0:
            who = record.get("answered_by") or "someone"
            return (f"query_id: query {query_id} was already answered "
                    f"(Option {option_letter(int(record['chosen']))}, by {who}); nothing changed")
        if query_id in self.accepted:
            return (f"query_id: query {query_id} was already answered from this page "
                    f"(Option {option_letter(self.accepted[query_id])}); nothing changed")
        if query_id in self.pending:
            return f"query_id: an answer to query {query_id} is already being sent; wait for the new posterior"
        num_options = len(record.get("options", ()))
        if not 0 <= chosen < num_options:
            named = f"Option {option_letter(chosen)}" if 0 <= chosen < 26 else f"option {chosen}"
            return (f"chosen: {named} is out of range: query {query_id} has {num_options} options "
                    f"(A..{option_letter(num_options - 1)})")
        return None
