"""The launcher's lifecycle manager: drives managed nodes through configure and activate.

The graph's nodes are ``rclpy.lifecycle`` nodes (``ird_ros.runtime.lifecycle``) that the
launcher starts with ``autostart:=false``: they come up unconfigured. ``LifecycleDriver`` runs
on the readiness probe's node (``ird_ros.launch.readiness``, one thread) and, per node process,
calls its lifecycle services, like Nav2's lifecycle manager:

1. ``discovering``: waits until ``/<node>/get_state`` and ``/<node>/change_state`` are discovered;
2. ``asking``: ``get_state``; unconfigured -> configure, inactive -> step 4, active -> done;
3. ``configuring``: ``change_state`` configure; ``success: false`` is a failure (the node logged
   ``configure failed: <reason>``, e.g. a parameter outside its allowed values) and the node is
   ``failed``: it stays up, unconfigured, and the launch fails naming it and the reason;
4. ``inactive``: waits until the launcher lets it activate (``may_activate``: the recorder
   first, the others once the recorder is ready and the nodes in their ``after`` are);
5. ``activating``: ``change_state`` activate -> ``active`` (or ``failed``).

A request unanswered for ``RESEND_AFTER`` seconds (a lost request or response; a slow transition
such as a worker pool's start holds the node's executor, so its answer comes late but in order)
is followed by a new ``get_state``, whose answer decides the next step: nothing is sent twice
that would fail the second time. A new process of the node (a respawn) starts again at 1.
No sleeps: the probe thread calls ``advance`` after each ``spin_once``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

__all__ = ["LifecycleDriver", "Track", "RESEND_AFTER", "ACTIVE", "FAILED"]

RESEND_AFTER = 5.0
ACTIVE = "active"
FAILED = "failed"
_CONFIGURE, _ACTIVATE = 1, 3  # lifecycle_msgs/msg/Transition ids


@dataclass
class Track:
    """Where one node process is in its start-up transitions."""

    pid: int
    phase: str = "discovering"
    future: Any = None
    sent_at: float = 0.0
    error: str = ""

    def describe(self) -> str:
        """What the process waits for, for the launcher's reports."""
        return {
            "discovering": "lifecycle services not discovered yet",
            "asking": "asked for its lifecycle state",
            "configuring": "configuring",
            "inactive": "inactive, waiting to be activated",
            "activating": "activating",
            ACTIVE: "active",
        }.get(self.phase, self.error or self.phase)


class LifecycleDriver:
    """Configures and activates managed nodes from ``node`` (the probe's rclpy node; not thread-safe)."""

    def __init__(self, node: Any) -> None:
        self._node = node
        self._clients: dict[str, tuple[Any, Any]] = {}
        self._tracks: dict[str, Track] = {}

    def _clients_of(self, name: str) -> tuple[Any, Any]:
        if name not in self._clients:
            from lifecycle_msgs.srv import ChangeState, GetState

            self._clients[name] = (self._node.create_client(GetState, f"/{name}/get_state"),
                                   self._node.create_client(ChangeState, f"/{name}/change_state"))
        return self._clients[name]

    def track(self, name: str, pid: int) -> Track:
        """The track of process ``pid`` of ``name`` (a new one for a new process)."""
        track = self._tracks.get(name)
        if track is None or track.pid != pid:
            track = self._tracks[name] = Track(pid)
        return track

    def _send(self, track: Track, phase: str, client: Any, request: Any) -> None:
        track.phase, track.future, track.sent_at = phase, client.call_async(request), time.monotonic()

    def _ask(self, name: str, track: Track) -> None:
        from lifecycle_msgs.srv import GetState

        self._send(track, "asking", self._clients_of(name)[0], GetState.Request())

    def _change(self, name: str, track: Track, phase: str, transition: int) -> None:
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        self._send(track, phase, self._clients_of(name)[1], ChangeState.Request(transition=Transition(id=transition)))

    def advance(self, name: str, pid: int, may_activate: bool) -> Track:
        """Take the next step(s) of ``name``'s process ``pid`` that can be taken now; its track."""
        track = self.track(name, pid)
        get_state, change_state = self._clients_of(name)
        if track.phase == "discovering":
            if not (get_state.service_is_ready() and change_state.service_is_ready()):
                return track
            self._ask(name, track)
        if track.phase in ("asking", "configuring", "activating"):
            future = track.future
            if not future.done():
                if time.monotonic() - track.sent_at > RESEND_AFTER:
                    self._ask(name, track)  # lost, or slow: its state says what happened
                return track
            self._answered(name, track, future.result())
        if track.phase == "inactive" and may_activate:
            self._change(name, track, "activating", _ACTIVATE)
        return track

    def _answered(self, name: str, track: Track, result: Any) -> None:
        if track.phase == "asking":
            label = str(result.current_state.label) if result is not None else "unknown"
            if label == "unconfigured":
                self._change(name, track, "configuring", _CONFIGURE)
            elif label in ("inactive", ACTIVE):
                track.phase = label
            elif label in ("configuring", "activating", "unknown"):
                self._ask(name, track)  # between two states: ask again
            else:
                track.phase, track.error = FAILED, f"in lifecycle state {label}"
        elif result is not None and result.success:
            track.phase = "inactive" if track.phase == "configuring" else ACTIVE
        else:
            what = "configure" if track.phase == "configuring" else "activate"
            track.phase, track.error = FAILED, f"{what} failed"

    def failure(self, name: str, pid: int | None) -> str:
        """Why process ``pid`` of ``name`` failed a transition ("" if it did not)."""
        track = self._tracks.get(name)
        return track.error if track is not None and track.pid == pid and track.phase == FAILED else ""

    def close(self) -> None:
        for clients in self._clients.values():
            for client in clients:
                self._node.destroy_client(client)
        self._clients.clear()
