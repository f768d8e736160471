"""A request sent to a service of the graph and not answered yet, and what happens when its
server drops out of the graph meanwhile (a node stopped with SIGSTOP, frozen, or starved).

Why this exists: DDS can drop a pending request when the client's participant stops hearing
from the server's (its lease, 20 s in Fast DDS, expires): the match between the client's request
writer and the server's request reader ends, and when the server is back its volatile reader
ignores what was sent before the new match. (Not always: a stopped process may find the request
in its socket buffer when continued and, its own lease timers not having run, answer it.) Without a remedy such a call waits until its
timeout (``tests/ros/test_stalls.py`` reproduces it: request sent to a node stopped for longer
than the lease, the node continued, no answer ever). The root is in DDS (volatile, reliable
service endpoints lose a request when the match is lost), so the remedy is here:

- ``poll()`` (called by ``done()``, hence by every wait of ``IrdClient``, at most 50 ms apart)
  watches ``service_is_ready()``: the server dropping out and coming back is recorded
  (``drops``, ``outage``).
- When the server is back and the request is ``resend``-able (pure computations, whose repeat
  gives the same answer: ``RESEND_SAFE``), the same request is sent again, at most
  ``MAX_RESENDS`` times; the first answer to any copy is the answer.
- Otherwise an answer may still come (a response the server sends after its return reaches the
  client once the match is back, usually within a second); if none came ``lost_grace`` s after
  the server's return, the call ends ``FAILED`` with a message that names the service, the
  outage, the grace and that the request may have been carried out.

Invariants: a PendingCall ends with the server's answer, or with that FAILED result, or (an
outage shorter than one poll, unseen) at the caller's timeout; it never resends a request that
is not ``resend``-able; its done-callbacks run once.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Generic, TypeVar

from ird_ros.client.results import CallResult, CallStatus, decode_answer
from ird_ros.graph import names

__all__ = ["PendingCall", "RESEND_SAFE", "MAX_RESENDS", "LOST_GRACE"]

T = TypeVar("T")

#: Services whose request may be sent twice: the same request gives the same answer (and
#: republishes the same posterior), so a resent request changes nothing but the wait.
RESEND_SAFE: frozenset[str] = frozenset({names.SRV_INFER})

#: Resends of one request at most (one per drop of its server).
MAX_RESENDS = 3

#: Seconds a request that is not resent waits, after its server came back, for an answer
#: before the call ends FAILED.
LOST_GRACE = 30.0


class PendingCall(Generic[T]):
    """A request sent and not answered yet: ``done()``, then ``result()`` (see the module doc).

    Args:
        service: the service name (for messages).
        client: the rclpy client the request was sent with.
        request: the request (kept for a resend).
        decode: makes the payload of a DONE answer.
        resend: send the request again when its server comes back after dropping out.
        lost_grace: seconds to wait for an answer after the server's return (no resend).
    """

    def __init__(self, service: str, client: Any, request: Any, decode: Callable[[Any], T] | None, *,
                 resend: bool = False, lost_grace: float = LOST_GRACE,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not lost_grace >= 0.0:
            raise ValueError(f"lost_grace must be >= 0 s, got {lost_grace!r}")
        self.service = service
        self.resend = bool(resend)
        self.lost_grace = float(lost_grace)
        self._client = client
        self._request = request
        self._decode = decode
        self._clock = clock
        self._callbacks: list[Callable[[], None]] = []
        self._fired = False
        self._futures: list[Any] = []
        self._winner: Any = None
        self.drops = 0  # times the server dropped out while this request was pending
        self.resends = 0
        self.outage = 0.0  # seconds the latest drop lasted
        self._down_since: float | None = None
        self._back_at: float | None = None  # the server's return, when no resend followed it
        self._lost: CallResult[T] | None = None
        self._send()

    # ------------------------------------------------------------------ state

    def _send(self) -> None:
        future = self._client.call_async(self._request)
        future.add_done_callback(lambda _future: self._fire())
        self._futures.append(future)

    def _answered(self) -> Any:
        """The future of the first answer (kept: a late answer to another copy changes nothing)."""
        if self._winner is None:
            self._winner = next((f for f in self._futures if f.done()), None)
        return self._winner

    @property
    def server_dropped(self) -> bool:
        """Whether the server dropped out of the graph at least once while the request was pending."""
        return self.drops > 0

    @property
    def server_absent(self) -> bool:
        """Whether the server dropped out and has not been seen back (as of the last poll)."""
        return self._down_since is not None

    def poll(self) -> None:
        """Follow the server's presence; resend or give up as the module docstring says."""
        if self._lost is not None or self._answered() is not None:
            return
        now = self._clock()
        if not self._client.service_is_ready():
            if self._down_since is None:
                self._down_since = now
                self.drops += 1
            self._back_at = None
            return
        if self._down_since is not None:  # the server is back
            self.outage = now - self._down_since
            self._down_since = None
            if self.resend and self.resends < MAX_RESENDS:
                self.resends += 1
                self._send()
                return
            self._back_at = now
        if self._back_at is not None and now - self._back_at >= self.lost_grace:
            self._lost = CallResult(self.service, CallStatus.FAILED, self._lost_message())
            self._forget()
            self._fire()

    def _lost_message(self) -> str:
        resent = f" (resent {self.resends} time(s))" if self.resends else ""
        return (f"no answer from {self.service}: its server dropped out of the graph for {self.outage:.1f} s "
                f"while this request was pending{resent} (its DDS participant lease expired: the node was "
                f"stopped, frozen or starved for about 20 s or more), and no answer came within "
                f"{self.lost_grace:g} s of its return, so the request or its answer was lost; it may have "
                f"been carried out: check before sending it again")

    def drop_note(self) -> str:
        """A sentence for a timeout message: whether (and how often) the server dropped out."""
        if not self.drops:
            return ""
        note = (f"\n{self.service}'s server dropped out of the graph {self.drops} time(s) while the request was "
                f"pending (node stopped, frozen or starved): DDS drops a request then; see ird_ros.client.pending")
        if self.server_absent:
            note += (f"\nThis client has not seen the server back for {self._clock() - self._down_since:.1f} s. If "
                     "the node runs again (the launcher says 'responding again'), this client's DDS participant may "
                     "have lost it for good: Fast DDS does not show a node again to a participant that expired it "
                     "alone (docs/limits.md, Stalled nodes); a new IrdClient discovers it")
        return note

    def _forget(self) -> None:
        """Stop waiting for answers to the copies sent (frees rclpy's pending-request entries)."""
        for future in self._futures:
            if not future.done():
                self._client.remove_pending_request(future)

    def _fire(self) -> None:
        if self._fired:
            return
        self._fired = True
        if self._lost is None and self._answered() is not None:
            self._forget()
        for callback in self._callbacks:
            callback()

    # ------------------------------------------------------------------ public

    def done(self) -> bool:
        """Whether the call has ended (answered, or given up as lost); polls the server first."""
        self.poll()
        return self._lost is not None or self._answered() is not None

    def add_done_callback(self, callback: Callable[[], None]) -> None:
        """Call ``callback()`` once when the call ends (while the client's node spins)."""
        if self._fired:
            callback()
        else:
            self._callbacks.append(callback)

    def result(self) -> CallResult[T]:
        """The answer (or the FAILED result of a lost request); ``RuntimeError`` before the call ended."""
        if self._lost is not None:
            return self._lost
        future = self._answered()
        if future is not None:
            return decode_answer(self.service, future.result(), self._decode)
        raise RuntimeError(f"{self.service}: no answer yet")
