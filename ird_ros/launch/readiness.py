"""Is a launched node ready? An rclpy probe node that drives the managed nodes' lifecycles and
reads the ROS graph (no fixed sleeps).

Managed nodes (``ird_ros.graph.nodes.is_managed``: the graph's own nodes) are configured and
activated by ``ird_ros.launch.lifecycle_driver.LifecycleDriver`` on the probe's node; once
active, only their ``ready_topics`` (and the recorder's recording, below) are checked here. The
graph checks below decide the readiness of unmanaged nodes (stand-ins).

``GraphProbe`` runs a node (``launcher``) in its own rclpy context in the graph's domain; the
launcher spins it and asks, for each starting node, what is still ``missing`` (an empty list:
ready). A node is ready when all of these hold:

1. its name is in the graph (``get_node_names_and_namespaces``);
2. every service of its ``services`` is listed for it (``get_service_names_and_types_by_node``);
3. every topic of its ``publishes`` has a publisher endpoint owned by it
   (``get_publishers_info_by_topic``) that no earlier process of that node owned (a GID not
   seen before: DDS keeps a SIGKILLed node's endpoints in the graph until its lease expires,
   about 20 s, and a respawned node must be judged by its own endpoints);
4. a message arrived on every topic of its ``ready_topics`` after the process started
   (latched topics: the probe subscribes transient local), unless the caller says not to
   wait for them.

Items 1-3 read the probe's graph cache, which can keep a node's older endpoint list for good (an
upstream race, ``ird_ros.launch.graph_view``): a node that has lacked only such items for a few
seconds is judged by a fresh participant's reading instead, and a note says so when that helps.

The recorder (``recorded`` topics given) is ready when it is in the graph, subscribes to each
of those topics, and, for each of them that is latched (transient local) and on which the
probe itself received a message, its status (``names.TOPIC_RECORDER_STATUS``) counts at least
one recorded message; ``recorder_lag`` lists the latched messages still missing from the bag.

``ReadinessMonitor`` runs the probe in a thread next to an ``ird_ros.launch.supervisor.Supervisor``:
it checks every ``starting`` child, calls ``Supervisor.mark_ready`` once nothing is missing,
keeps the recorder's lag up to date after the recorder was ready, and watches every ``ready``
child for stalls (``ird_ros.launch.liveness``: process stopped, or no answer to a parameter
request), which it reports to the supervisor as ``ProcessStalled`` / ``ProcessRecovered`` events.
The pings go from a second node, ``launcher_ping``, in a participant of its own
(``PingParticipant``) that liveness may replace when DDS stops showing it a node; that participant
and the checks run in a process of their own (``ird_ros.launch.liveness.LivenessProcess``), so a
ping stuck in the DDS transport cannot freeze the launcher; a probe process that stops answering
is replaced and reported through ``on_note``.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import json
import os
import threading
import time
from dataclasses import replace
from typing import Any, Callable, Iterable, Mapping, Sequence

from ird_ros.graph import names
from ird_ros.graph.nodes import NodeSpec
from ird_ros.launch import graph_view
from ird_ros.launch.events import ChildInfo, ChildState, ProcessRecovered, ProcessStalled
from ird_ros.launch.lifecycle_driver import ACTIVE, FAILED, LifecycleDriver
from ird_ros.launch.liveness import (PING_NODE, PING_PERIOD, PING_TIMEOUT, LivenessProcess, PingParticipant,
                                     _close_participant, _open_participant)
from ird_ros.launch.supervisor import Supervisor

__all__ = ["GraphProbe", "PingParticipant", "ReadinessMonitor", "PROBE_NODE", "PING_NODE"]

PROBE_NODE = names.NODE_LAUNCHER


class GraphProbe:
    """The readiness probe (see the module docstring); not thread-safe: one thread uses it.

    Args:
        domain_id: the graph's ROS domain.
        env: the children's environment (its discovery range and log dir apply to the probe).
        recorder_status: also follow ``/recorder/status`` (for ``recorder_lag``).
    """

    def __init__(self, domain_id: int, env: Mapping[str, str], recorder_status: bool = False) -> None:
        self._ctx, self._node, self._executor = _open_participant(PROBE_NODE, domain_id, env)
        self._subs: dict[str, Any] = {}
        self._received: dict[str, float] = {}  # topic -> monotonic time of the last message
        self._latched: dict[str, bool] = {}  # topic -> every publisher offers transient local
        self._recorder_counts: dict[str, int] = {}
        self._gids: dict[str, dict[int, set]] = {}  # node -> pid -> publisher GIDs it owned
        if recorder_status:
            self._follow_recorder_status()

    def _follow_recorder_status(self) -> None:
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        def status(msg: Any) -> None:
            with contextlib.suppress(ValueError, AttributeError, KeyError, TypeError):
                self._recorder_counts = dict(json.loads(msg.data)["counts"])

        self._node.create_subscription(String, names.TOPIC_RECORDER_STATUS, status, QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))

    @property
    def node(self) -> Any:
        """The probe's rclpy node (spun by ``spin_once``)."""
        return self._node

    def spin_once(self, timeout: float) -> None:
        """Handle one ROS event (message, discovery) or return after ``timeout`` s."""
        self._executor.spin_once(timeout_sec=timeout)

    def present(self) -> set[tuple[str, str]]:
        """``(name, namespace)`` of every node in the graph."""
        return set(self._node.get_node_names_and_namespaces())

    def _watch_topic(self, topic: str) -> None:
        """Subscribe (raw, QoS matching the publishers) once the topic's type is visible."""
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        types = dict(self._node.get_topic_names_and_types()).get(topic)
        infos = self._node.get_publishers_info_by_topic(topic)
        if not types or not infos:
            return
        pkg, kind, name = types[0].split("/")
        msg_class = getattr(importlib.import_module(f"{pkg}.{kind}"), name)
        transient = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
        )

        def got(_raw: bytes) -> None:
            self._received[topic] = time.monotonic()

        self._subs[topic] = self._node.create_subscription(msg_class, topic, got, qos, raw=True)
        self._latched[topic] = transient

    def missing(
        self,
        spec: NodeSpec,
        pid: int,
        started_at: float,
        present: set[tuple[str, str]],
        *,
        wait_topics: bool = True,
        recorded: Sequence[str] | None = None,
        managed: bool = False,
        view: Any | None = None,
    ) -> list[str]:
        """What the process ``pid`` of ``spec`` still lacks to be ready (empty list: ready).

        ``started_at``: its ``time.monotonic()`` start (messages before it do not count);
        ``present``: ``present()``; ``wait_topics``: require its ``ready_topics``;
        ``recorded``: the topics it must record (the recorder only); ``managed``: a lifecycle
        node, already active: only its ready topics (and a recorder's recording) are checked,
        not its services and publishers in the graph. ``view``: a node whose reading of the graph
        is used instead of the probe's (``ird_ros.launch.graph_view``; ``present`` from it too).
        """
        node = self._node if view is None else view
        name = spec.name
        missing: list[str] = []
        if not managed and (name, "/") not in present:
            return [f"node /{name} not in the graph"]
        if managed:
            spec = replace(spec, services=(), publishes=())
        if spec.services:
            served = {s for s, _t in node.get_service_names_and_types_by_node(name, "/")}
            missing += [f"service {s} not available" for s in spec.services if s not in served]
        by_pid = self._gids.setdefault(name, {})
        earlier = set().union(*(g for p, g in by_pid.items() if p != pid))
        for topic in spec.publishes:
            own = {tuple(i.endpoint_gid) for i in node.get_publishers_info_by_topic(topic)
                   if i.node_name == name and i.node_namespace == "/"}
            new = own - earlier
            if not new:
                missing.append(f"no publisher of {topic} from /{name}" + (" (new instance)" if own else ""))
            by_pid.setdefault(pid, set()).update(new)
        if wait_topics:
            for topic in spec.ready_topics:
                if topic not in self._subs:
                    self._watch_topic(topic)
                if self._received.get(topic, -1.0) < started_at:
                    missing.append(f"no message on {topic} yet")
        if missing and any(not m.startswith("no message on ") for m in missing):
            count = node.get_node_names_and_namespaces().count((name, "/"))
            if count > 1:  # a query by node name reads one of them: an older process's, another graph's
                missing.append(f"node /{name} {count} times in the graph")
        if recorded is not None:
            for topic in recorded:
                subs = node.get_subscriptions_info_by_topic(topic)
                if not any(i.node_name == name for i in subs):
                    missing.append(f"not subscribed to {topic}")
                    continue
                if topic not in self._subs:
                    self._watch_topic(topic)
            missing += self.recorder_lag(recorded)
        return missing

    def recorder_lag(self, recorded: Sequence[str]) -> list[str]:
        """Latched messages that exist (the probe received one) but are not in the bag yet."""
        return [
            f"latched message on {topic} not recorded yet"
            for topic in recorded
            if self._latched.get(topic) and topic in self._received and self._recorder_counts.get(topic, 0) == 0
        ]

    def close(self) -> None:
        """Shut the executor, node and context down (errors ignored: used while stopping)."""
        _close_participant(self._ctx, self._node, self._executor)


class ReadinessMonitor:
    """Marks the supervisor's starting children ready when the probe finds nothing missing.

    Args:
        supervisor: runs the children named in ``specs``.
        specs: what each child must offer (``NodeSpec`` by name).
        domain_id, env: as for ``GraphProbe``.
        skip_ready_topics: children not to wait for on their ``ready_topics``.
        recorder: the recorder's name, if one runs, and ``recorded``: the topics it must record.
        on_change: called (without locks held) after every check that may change an answer.
        ping_period, ping_timeout: of the liveness checks (``ird_ros.launch.liveness``).
        on_note: receives a line when the liveness probe's process was replaced.
        liveness_target: the probe process's function (default ``ird_ros.launch.liveness.serve``).
    """

    def __init__(
        self,
        supervisor: Supervisor,
        specs: Mapping[str, NodeSpec],
        domain_id: int,
        env: Mapping[str, str],
        *,
        skip_ready_topics: Iterable[str] = (),
        recorder: str | None = None,
        recorded: Sequence[str] = (),
        on_change: Callable[[], None] = lambda: None,
        ping_period: float = PING_PERIOD,
        ping_timeout: float = PING_TIMEOUT,
        on_note: Callable[[str], None] = lambda text: None,
        liveness_target: Callable[..., None] | None = None,
        managed: Iterable[str] = (),
    ) -> None:
        self._sup = supervisor
        self._managed = set(managed)
        self._specs = dict(specs)
        self._skip = set(skip_ready_topics)
        self._recorder = recorder
        self._recorded = list(recorded)
        self._on_change = on_change
        self._probe = GraphProbe(domain_id, env, recorder_status=recorder is not None)
        self._driver = LifecycleDriver(self._probe.node)
        self._on_note = on_note
        self._view = graph_view.SecondView(domain_id, env)
        self._second_found: set[tuple[str, int]] = set()
        self._liveness = LivenessProcess(domain_id, env, period=ping_period, ping_timeout=ping_timeout,
                                         **({} if liveness_target is None else {"target": liveness_target}))
        self._lock = threading.Lock()
        self._missing: dict[str, tuple[int, list[str]]] = {}  # name -> (pid, what it lacks)
        self._failures: dict[tuple[str, int | None], str] = {}  # (name, pid) -> failed transition
        self._lag: list[str] = []
        self._stalled: dict[str, float] = {}
        self._stall_notes: dict[str, str] = {}  # stalled name -> what the last liveness check saw
        self._checked_at = time.monotonic()
        self._error: BaseException | None = None
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._run, name="readiness", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def failure(self, name: str, pid: int | None) -> str:
        """Why the process ``pid`` of managed node ``name`` failed a transition ("" if it did not)."""
        with self._lock:
            return self._failures.get((name, pid), "")

    def missing(self, name: str, pid: int | None) -> list[str]:
        """What the process ``pid`` of ``name`` lacked at the last check."""
        with self._lock:
            seen_pid, what = self._missing.get(name, (None, []))
        return list(what) if seen_pid == pid else ["process started"]

    def recorder_lag(self) -> list[str]:
        """Latched messages not in the bag yet (checked once the recorder was ready)."""
        with self._lock:
            return list(self._lag)

    @property
    def error(self) -> BaseException | None:
        """Why the probe thread ended early (None while it runs or after ``close``)."""
        with self._lock:
            return self._error

    def _run(self) -> None:
        try:
            while not self._closing.is_set():
                self._probe.spin_once(0.05)
                infos = self._sup.infos()
                self._check([i for i in infos.values() if i.state is ChildState.STARTING])
                if not self._sup.stopping:
                    self._report_liveness(infos)
                rec = infos.get(self._recorder) if self._recorder is not None else None
                if rec is not None and rec.state is ChildState.READY:
                    lag = self._probe.recorder_lag(self._recorded)
                    with self._lock:
                        self._lag = lag
                    self._on_change()
        except BaseException as exc:  # noqa: BLE001 - surfaced through ``error``
            if not self._closing.is_set():
                with self._lock:
                    self._error = exc
            self._on_change()

    def _check(self, starting: list[ChildInfo]) -> None:
        if not starting:
            self._view.tick()
            return
        present = self._probe.present()
        infos = self._sup.infos()
        for info in starting:
            assert info.pid is not None
            managed = info.name in self._managed
            try:
                missing = self._lifecycle(info, infos) if managed else []
                if not missing:
                    missing = self._graph_missing(info, present, managed)
            except Exception as exc:  # noqa: BLE001 - e.g. the node left the graph meanwhile
                missing = [f"graph query failed: {exc}"]
            with self._lock:
                self._missing[info.name] = (info.pid, missing)
            if not missing:
                self._sup.mark_ready(info.name, info.pid)
            self._on_change()
        self._view.tick()

    def _graph_missing(self, info: ChildInfo, present: set[tuple[str, str]], managed: bool) -> list[str]:
        """The probe's answer for ``info``; when it has named only graph entries for
        ``SECOND_VIEW_AFTER`` s, a fresh participant's reading of the graph decides those
        (``ird_ros.launch.graph_view``), and the first time that finds them, a note says so."""
        assert info.pid is not None
        ask = functools.partial(self._probe.missing, self._specs[info.name], info.pid, info.started_at,
                                wait_topics=info.name not in self._skip,
                                recorded=self._recorded if info.name == self._recorder else None, managed=managed)
        missing = ask(present)
        if not graph_view.graph_only(missing) or time.monotonic() - info.started_at < graph_view.SECOND_VIEW_AFTER:
            return missing
        view = self._view.node()
        if view is None:
            return missing
        second = ask(self._view.present(), view=view)
        if not graph_view.graph_only(second) and (info.name, info.pid) not in self._second_found:
            self._second_found.add((info.name, info.pid))
            self._on_note(f"{info.name} (pid {info.pid}): the probe's reading of the graph lacked "
                          f"{'; '.join(missing)}; a fresh participant's reading has it "
                          "(ros2/rmw_fastrtps#792, see ird_ros.launch.graph_view)")
        return second

    def _lifecycle(self, info: ChildInfo, infos: Mapping[str, ChildInfo]) -> list[str]:
        """Drive a managed node's transitions (``LifecycleDriver``); what it lacks until active.

        It may activate once the recorder (if one runs, and it is not the recorder) and the
        launched nodes of its ``after`` are ready: the recorder subscribes to everything before
        anything is published, and a node's inputs are published before it starts."""
        assert info.pid is not None
        first = [self._recorder] if self._recorder is not None and info.name != self._recorder else []
        before = [n for n in (*first, *self._specs[info.name].after) if n in infos]
        waiting = [n for n in before if infos[n].state is not ChildState.READY]
        track = self._driver.advance(info.name, info.pid, may_activate=not waiting)
        if track.phase == ACTIVE:
            return []
        if track.phase == FAILED:
            with self._lock:
                self._failures[(info.name, info.pid)] = track.error
            return [track.error]
        what = track.describe()
        if track.phase == "inactive" and waiting:
            what += f" (after {', '.join(waiting)})"
        return [what]

    def _report_liveness(self, infos: Mapping[str, ChildInfo]) -> None:
        changes = self._liveness.check(infos)
        if self._liveness.hung is not None:
            note, self._liveness.hung = self._liveness.hung, None
            self._on_note(note)
        for change in changes:
            if change.stalled:
                self._sup.note(change.name, change.pid, ProcessStalled, reason=change.reason)
            else:
                self._sup.note(change.name, change.pid, ProcessRecovered, stalled_for=change.stalled_for)
        stalled = self._liveness.stalled()
        notes = {name: self._liveness.describe(name) for name in stalled}
        with self._lock:
            self._stalled, self._stall_notes, self._checked_at = stalled, notes, time.monotonic()

    def stall_note(self, name: str) -> str:
        """What the last liveness check saw of ``name`` if it is stalled now, and how long ago
        that check was (a probe thread that stopped checking shows here); else ``""``."""
        with self._lock:
            note = self._stall_notes.get(name, "")
            return f"{note}; last check {time.monotonic() - self._checked_at:.1f} s ago" if note else ""

    def stalled(self) -> dict[str, float]:
        """Children seen stalled and not recovered (name -> monotonic time seen), as of the last check."""
        with self._lock:
            return dict(self._stalled)

    def close(self) -> None:
        """End the thread and the probe."""
        self._closing.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self._driver.close()
        self._view.close()
        self._probe.close()
        self._liveness.close()
