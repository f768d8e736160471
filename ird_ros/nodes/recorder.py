"""Bag recorder node (``recorder``): a small stand-in for ``ros2 bag record``.

Subscribes with ``raw=True`` (the callback receives the serialized CDR bytes, nothing is
deserialized) and writes the bytes with the ``rosbags`` library into a rosbag2 bag
(format version 9, MCAP storage) that opens with ``rosbags``, ``ros2 bag`` and Foxglove::

    python -m ird_ros.nodes.recorder --ros-args -p output_dir:=bags/run1 \\
        -p "topics:=[/world/terrain, /plan, /odom, /rob/status]"
    python -m ird_ros.nodes.recorder --ros-args --params-file msgs_config/params/graph.yaml \\
        -p output_dir:=bags/run2          # topics from graph.yaml's recorder section

Parameters (node ``recorder``; types and defaults in ``PARAMETERS``):

- ``output_dir`` (string, required): the bag folder to create. An existing path is refused
  (the node exits with status 2 and says so): a bag is never overwritten or appended to.
  ``{stamp}`` in it is replaced by the local time (``runs/bag_{stamp}`` ->
  ``runs/bag_20250101_120000``), so a params file can give a fresh folder per run.
- ``topics``: topics to record; empty (the default) = every topic that has a publisher,
  discovered every ``discovery_period`` seconds, minus ``exclude_topics``.
- ``exclude_topics``: topics never recorded when ``topics`` is empty.
- ``discovery_period`` (seconds): how often the graph is polled for new topics / publishers.
- ``queue_depth``: history depth of the recording subscriptions.
- ``flush_period`` (seconds, 0 = off): how often the bag is checkpointed
  (``ird_ros.bags.repair.checkpoint``): the buffered messages go to disk as a finished chunk
  followed by a provisional MCAP end, fsynced, and ``metadata.yaml`` is rewritten. Checkpoints
  run in a thread of their own on a monotonic deadline (every ``flush_period`` s from the
  previous one's start), so a busy executor cannot delay them (a ROS timer could: under load one
  was seen 0.6 s late). Bound (``loss_bound``): a SIGKILL (or a crash of the machine) loses only
  the messages the recorder received in the last ``flush_period + CHECKPOINT_ALLOWANCE`` s,
  plus those DDS had not delivered to it yet (under CPU load the recorder may lag behind the
  publishers; that lag is not the recorder's to bound).

A topic is subscribed once a publisher of it is seen (its type is taken from the graph),
with the publishers' QoS: transient local when every publisher offers transient local (so
latched maps, proxy, posterior and plan published before the recorder joined are still
recorded), else volatile; reliable when every publisher is reliable, else best effort.
Messages are stamped with their receive time (the node clock).

Types: standard ones from rosbags' ``Stores.ROS2_JAZZY``; others (``ird_msgs``) from their
installed ``.msg`` files (``<prefix>/share/<pkg>/msg``, via the ament index or, in a pip venv
without ``AMENT_PREFIX_PATH``, the interpreter's prefix),
nested types included.

Status: ``/recorder/status`` (std_msgs/String, transient local) carries JSON
``{"output_dir": ..., "counts": {topic: n}}``, republished (at most every 0.1 s) when a count
changes; ``ird_ros.launch.launcher`` uses it to know that the latched messages reached the bag.

Stopping: SIGINT and SIGTERM stop spinning, drain what already arrived, close the writer
(MCAP summary + ``metadata.yaml``), log the number of messages per topic and exit 0. The
bag is complete and readable after either signal. After a SIGKILL the bag as of the last
checkpoint normally opens as it is (``rosbags``, ``mcap``); ``scripts/reindex_bag.py BAG``
rebuilds its index and summary, and is needed when the kill hit a write.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import rclpy
from rclpy.exceptions import ParameterUninitializedException
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import String

from ird_ros.bags.repair import checkpoint, close_writer
from ird_ros.bags.storage import register_type
from ird_ros.graph import names
from ird_ros.runtime.lifecycle import ManagedNode, start_up
from ird_ros.runtime.node_main import StartupError
from ird_ros.runtime.node_params import Param

__all__ = ["RecorderError", "RecorderNode", "PARAMETERS", "CHECKPOINT_ALLOWANCE", "loss_bound", "find_installed_msg",
           "main"]

NODE_NAME = names.NODE_RECORDER
PARAMETERS: dict[str, Param] = {
    "output_dir": Param("", "The bag folder to create (required; {stamp} = local date and time)"),
    "topics": Param((), "Topics to record (empty = every topic with a publisher, minus exclude_topics)"),
    "exclude_topics": Param(("/rosout", "/parameter_events"), "Topics not recorded when topics is empty"),
    "discovery_period": Param(0.25, "Seconds between polls of the graph for new topics and publishers"),
    "queue_depth": Param(1000, "History depth of the recording subscriptions"),
    "flush_period": Param(0.5, "Seconds between checkpoints of the bag: at most this much is lost to a SIGKILL (0 = off)"),
}
CHECKPOINT_ALLOWANCE = 0.25
"""Seconds allowed for one checkpoint (chunk, metadata.yaml, fsync: about 4 ms when idle) plus the
checkpoint thread's wake-up under CPU load."""


def loss_bound(flush_period: float) -> float:
    """Seconds before a SIGKILL within which a received message may be missing from the bag."""
    return float(flush_period) + CHECKPOINT_ALLOWANCE


STATUS_TOPIC = names.TOPIC_RECORDER_STATUS
"""std_msgs/String, latched: JSON ``{"output_dir": ..., "counts": {topic: messages}}``."""


class RecorderError(StartupError):
    """A configuration problem the recorder cannot start with (printed, exit status 2)."""


def _share_dirs(pkg: str) -> list[Path]:
    """Candidate ``share/<pkg>`` folders: the ament index, this interpreter's prefix, and
    the prefix the package's Python module is installed under.

    In a pip venv ``AMENT_PREFIX_PATH`` is usually unset (nothing sources a setup file), so
    the ament index alone finds nothing; the venv prefix holds ``share/<pkg>`` all the same.
    """
    dirs: list[Path] = []
    try:
        from ament_index_python.packages import get_package_share_directory

        dirs.append(Path(get_package_share_directory(pkg)))
    except Exception:  # noqa: BLE001 - PackageNotFoundError, or AMENT_PREFIX_PATH unset
        pass
    dirs.append(Path(sys.prefix) / "share" / pkg)
    with contextlib.suppress(Exception):
        spec = importlib.util.find_spec(pkg)
        if spec is not None and spec.origin:
            # <prefix>/lib/pythonX.Y/site-packages/<pkg>/__init__.py
            dirs.append(Path(spec.origin).resolve().parents[4] / "share" / pkg)
    return dirs


def find_installed_msg(typename: str) -> str | None:
    """The text of an installed ``pkg/msg/Name`` definition, or None (see ``_share_dirs``)."""
    pkg, kind, name = typename.split("/")
    for share in _share_dirs(pkg):
        path = share / kind / f"{name}.msg"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    return None


def _import_msg_class(typename: str) -> Any:
    pkg, kind, name = typename.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def _qos_time(duration: Any) -> QosTime:
    ns = int(getattr(duration, "nanoseconds", 0))
    ns = min(max(ns, 0), 2**63 - 1)
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def _bag_qos(profile: Any) -> Qos:
    """An rclpy QoSProfile (as discovered) as a rosbags ``Qos`` for the bag's metadata."""

    def conv(enum_cls: Any, value: Any, default: Any) -> Any:
        try:
            return enum_cls[value.name]
        except (KeyError, AttributeError):
            return default

    return Qos(
        history=conv(QosHistory, profile.history, QosHistory.UNKNOWN),
        depth=int(profile.depth),
        reliability=conv(QosReliability, profile.reliability, QosReliability.UNKNOWN),
        durability=conv(QosDurability, profile.durability, QosDurability.UNKNOWN),
        deadline=_qos_time(profile.deadline),
        lifespan=_qos_time(profile.lifespan),
        liveliness=conv(QosLiveliness, profile.liveliness, QosLiveliness.UNKNOWN),
        liveliness_lease_duration=_qos_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


def subscription_qos(publisher_profiles: list[Any], depth: int) -> QoSProfile:
    """The recording subscription's QoS, compatible with every given publisher profile."""
    transient = bool(publisher_profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publisher_profiles
    )
    reliable = all(p.reliability == ReliabilityPolicy.RELIABLE for p in publisher_profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
    )


class RecorderNode(ManagedNode):
    """Records raw messages into a rosbag2/MCAP bag (managed): the bag is created at configure,
    topics are discovered and recorded while active, the bag is closed at cleanup (or ``close()``)."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        self.writer: Writer | None = None
        self._flush_thread: threading.Thread | None = None
        self._flush_stop = threading.Event()
        self._recording_subs: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.bag_created = False  # a configure made the bag folder (summary() then describes it)
        super().__init__(NODE_NAME, **kwargs)

    def configure(self, p: dict[str, Any]) -> None:
        out = str(p["output_dir"] or "").strip()
        if not out:
            raise RecorderError("parameter output_dir is required (the bag folder to create), e.g. "
                                "--ros-args -p output_dir:=bags/run1")
        if "{stamp}" in out:
            out = out.replace("{stamp}", time.strftime("%Y%m%d_%H%M%S"))
        self.output_dir = Path(out).expanduser().resolve()
        if self.output_dir.exists():
            raise RecorderError(f"output_dir {self.output_dir} already exists: refusing to overwrite or "
                                "append to it; choose a new folder")
        self.topics: list[str] = [t for t in self._string_array("topics") if t]
        self.exclude = set(self._string_array("exclude_topics"))
        self.depth = int(p["queue_depth"])
        try:
            self.output_dir.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecorderError(f"output_dir {self.output_dir}: cannot make its folder: {exc.strerror or exc}") from None

        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        # The writer is used by the executor's callbacks and by the checkpoint thread: one at a time.
        self._writer_lock = threading.Lock()
        self.writer = Writer(self.output_dir, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.bag_created = True
        checkpoint(self.writer)  # metadata.yaml and a readable (empty) MCAP from the start
        self.counts = {}
        self._recording_conns: dict[str, Any] = {}
        self._recording_subs = {}
        self._given_up: set[str] = set()
        self._dirty = False

        # what has been recorded so far, for the launcher's readiness check and for humans
        self._status_pub = self.create_publisher(String, STATUS_TOPIC, QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self._status_sent: dict[str, int] | None = None
        self._status_timer = self.create_timer(0.1, self._publish_status)
        period = float(p["discovery_period"])
        self._discovery_timer = self.create_timer(max(period, 0.02), self._discover)
        self.flush_period = float(p["flush_period"])
        self._flush_stop = threading.Event()
        self._flush_thread = None
        if self.flush_period > 0:
            self._flush_thread = threading.Thread(target=self._checkpoints, name="recorder-checkpoints", daemon=True)
            self._flush_thread.start()

    def activate(self) -> None:
        self._status_sent = None  # publish the counts again
        self._discover()
        what = ", ".join(self.topics) if self.topics else "all topics"
        self.get_logger().info(f"recording {what} into {self.output_dir} (rosbag2 v9, MCAP)")

    def release(self) -> None:
        self.close()

    def _string_array(self, name: str) -> list[str]:
        try:
            param = self.get_parameter(name)
        except ParameterUninitializedException:  # statically typed, never set: empty
            return []
        if param.type_ == Parameter.Type.NOT_SET or param.value is None:
            return []
        return [str(v) for v in param.value]

    # ----------------------------------------------------------------- discovery

    def _wanted(self, topic: str) -> bool:
        if self.topics:
            return topic in self.topics
        return topic not in self.exclude

    def _discover(self) -> None:
        if self.writer is None or not self.is_active:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recording_subs or topic in self._given_up or not self._wanted(topic):
                continue
            infos = self.get_publishers_info_by_topic(topic)
            infos = [i for i in infos if not (i.node_name == self.get_name() and i.node_namespace == self.get_namespace())]
            if not infos:
                continue  # no publisher (yet): its QoS is unknown, look again later
            self._subscribe(topic, types, infos)

    def _subscribe(self, topic: str, types: list[str], infos: list[Any]) -> None:
        msgtype = types[0]
        if len(types) > 1:
            self.get_logger().warning(f"{topic} has several types {types}: recording {msgtype}")
        try:
            msg_class = _import_msg_class(msgtype)
            register_type(self.typestore, msgtype, find_installed_msg)
        except Exception as exc:  # type not installed here: can't subscribe
            self._given_up.add(topic)
            self.get_logger().error(f"not recording {topic}: type {msgtype} unavailable ({exc})")
            return
        profiles = [i.qos_profile for i in infos]
        with self._writer_lock:
            assert self.writer is not None
            conn = self.writer.add_connection(
                topic, msgtype, typestore=self.typestore, offered_qos_profiles=[_bag_qos(p) for p in profiles]
            )
            self._dirty = True  # the next checkpoint lists the topic in metadata.yaml
        self._recording_conns[topic] = conn
        self.counts[topic] = 0
        qos = subscription_qos(profiles, self.depth)
        self._recording_subs[topic] = self.create_subscription(
            msg_class, topic, self._make_callback(topic, conn), qos, raw=True
        )
        self.get_logger().info(
            f"recording {topic} [{msgtype}] ({qos.durability.name.lower()}, {qos.reliability.name.lower()})"
        )

    def _make_callback(self, topic: str, conn: Any) -> Callable[[bytes], None]:
        subscribed = time.monotonic()

        def callback(data: bytes) -> None:
            with self._writer_lock:
                if self.writer is None or not self.is_active:  # inactive: nothing is recorded
                    return
                self.writer.write(conn, self.get_clock().now().nanoseconds, data)
                self._dirty = True
            self.counts[topic] += 1
            if self.counts[topic] == 1:
                self.get_logger().info(
                    f"first message on {topic}, {time.monotonic() - subscribed:.2f} s after subscribing")

        return callback

    def _publish_status(self) -> None:
        if self.writer is None or self._status_sent == self.counts:
            return
        self._status_sent = dict(self.counts)
        self._status_pub.publish(String(data=json.dumps({"output_dir": str(self.output_dir), "counts": self._status_sent})))

    @property
    def recorded_topics(self) -> list[str]:
        return sorted(self._recording_subs)

    # ----------------------------------------------------------------- output

    def flush(self) -> None:
        """Checkpoint the bag if anything changed (rosbags keeps up to 1 MiB in memory)."""
        with self._writer_lock:
            if self.writer is None or not self._dirty:
                return
            checkpoint(self.writer)
            self._dirty = False

    def _checkpoints(self) -> None:
        """The checkpoint thread: ``flush()`` every ``flush_period`` s from the previous start."""
        due = time.monotonic() + self.flush_period
        while not self._flush_stop.wait(max(0.0, due - time.monotonic())):
            try:
                self.flush()
            except Exception as exc:  # noqa: BLE001 - a failed checkpoint is logged; recording goes on
                self.get_logger().error(f"checkpoint of {self.output_dir} failed: {exc!r}")
            due = max(due + self.flush_period, time.monotonic())

    def close(self) -> dict[str, int]:
        """Stop the checkpoints, close the bag (index, summary, metadata.yaml); idempotent. Returns the counts."""
        self._flush_stop.set()
        if self._flush_thread is not None:
            self._flush_thread.join()
        if self.writer is not None:
            for sub in self._recording_subs.values():
                self.destroy_subscription(sub)
            self._recording_subs = {}
            with self._writer_lock:
                writer, self.writer = self.writer, None
                close_writer(writer)
        return dict(self.counts)

    def summary(self) -> str:
        total = sum(self.counts.values())
        lines = [f"bag {self.output_dir}: {total} messages on {len(self.counts)} topics"]
        width = max([len(t) for t in self.counts] + [5])
        for topic in sorted(self.counts):
            lines.append(f"  {topic:<{width}}  {self.counts[topic]:>7}")
        return "\n".join(lines)


def _drain(executor: SingleThreadedExecutor, node: RecorderNode, max_seconds: float = 2.0) -> None:
    """Take what already arrived before closing: spin until a pass brings nothing new."""
    # Timers first: rclpy runs a due timer before pending messages, so after a busy spell (a
    # starved process: SIGINT lands with status/discovery timers due) the first pass ran a
    # timer, recorded nothing and ended the drain with messages still queued (the last
    # /rob/status and /odom of a run went missing from the bag).
    for name in ("_status_timer", "_discovery_timer"):  # absent when configure failed
        if hasattr(node, name):
            node.destroy_timer(getattr(node, name))
    deadline = time.monotonic() + max_seconds
    while time.monotonic() < deadline:
        before = sum(node.counts.values())
        executor.spin_once(timeout_sec=0.02)
        if sum(node.counts.values()) == before:
            break


def main(args: list[str] | None = None) -> int:
    # Own signal handling: SIGINT/SIGTERM only set a flag, the main loop closes the bag.
    stop = threading.Event()

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rclpy.init(args=sys.argv if args is None else args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = RecorderNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        if node.autostart and not start_up(node):  # else the launcher configures and activates it
            print(f"[recorder] error: {node.transition_error}", file=sys.stderr, flush=True)
            executor.shutdown()
            node.destroy_node()
            return 2
        try:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
            if rclpy.ok():
                _drain(executor, node)
        finally:
            node.close()
            if node.bag_created:
                node.get_logger().info(node.summary())
            executor.shutdown()
            node.destroy_node()
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
