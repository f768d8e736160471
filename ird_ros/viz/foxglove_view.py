"""The live view's Foxglove WebSocket server: scene data (:mod:`ird_ros.viz.scene`) -> Foxglove channels.

ROS-free: it imports ``foxglove`` (foxglove-sdk, which serves the Foxglove WebSocket protocol,
subprotocol ``foxglove.sdk.v1``) and numpy. :class:`LiveView` owns one ``foxglove.Context`` and
one server, reached through a :class:`ird_ros.viz.gate.Gate` on ``host:port`` (loopback by
default; any other address logs a warning: the server has no authentication). The gate refuses
a handshake whose ``Host`` is not loopback (while bound to loopback) or whose ``Origin`` is not
allowed (loopback origins and ``allowed_origins``) with 403, then relays to the SDK's server on
an ephemeral loopback port.

Channels (:data:`CHANNELS`): Grid (protobuf ``foxglove.Grid``) for the ground-truth terrain, the
perceived terrain and the risk map; SceneUpdate (protobuf ``foxglove.SceneUpdate``) for the plans
(one line entity per plan label) and for Rob (a cube at its pose and its trail); PosesInFrame
for Rob's trail as poses; JSON for the posterior per terrain, the designer's question and Rob's
status.

Invariants:

- Every channel shows state: the latest message of each channel is kept and logged again to the
  client that subscribes, and to that client only (``on_subscribe`` gives the client, whose id is
  its sink id; the SDK has the subscription in place when it calls it), so a client that connects
  late still sees the map, the plans and the posterior, and a new client costs the others nothing.
- Logging is serialised by one lock: a re-log on subscribe never overtakes a newer message.
- Messages are stamped with their ROS message's stamp; the log time is the wall clock now. A stamp
  before the epoch (``sec < 0``: Foxglove's timestamps are unsigned) is shown as 0.
"""

from __future__ import annotations

import json
import math
import threading
import time
from typing import Any, Callable

import foxglove
from foxglove.channels import GridChannel, PosesInFrameChannel, SceneUpdateChannel
from foxglove.messages import (
    Color,
    CubePrimitive,
    Grid,
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    Pose,
    PosesInFrame,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector2,
    Vector3,
)
from foxglove.websocket import ServerListener

from ird_ros.viz.gate import DEFAULT_ALLOWED_ORIGINS, Gate
from ird_ros.viz.scene import RGBA, ROB_COLOR, GridLayer, Line, RobTrail, hex_rgba
from ird_ros.web.limits import is_loopback

__all__ = ["LiveView", "CHANNELS", "GRID_CHANNELS", "SCENE_CHANNELS", "JSON_CHANNELS", "POSES_CHANNELS",
           "DEFAULT_PORT", "DEFAULT_ALLOWED_ORIGINS", "grid_message", "line_primitive", "bind_warning",
           "port_in_use_message"]

DEFAULT_PORT = 8766
"""The live view's port: not Foxglove's 8765, which the designer's web page uses."""

GRID_CHANNELS: dict[str, str] = {"terrain": "/viz/terrain", "perceived": "/viz/perceived", "risk": "/viz/risk_map"}
SCENE_CHANNELS: dict[str, str] = {"plans": "/viz/plans", "rob": "/viz/rob"}
POSES_CHANNELS: dict[str, str] = {"trail": "/viz/rob_trail"}
JSON_CHANNELS: dict[str, str] = {"posterior": "/viz/posterior", "query": "/viz/query", "rob_status": "/viz/rob_status"}
CHANNELS: dict[str, str] = GRID_CHANNELS | SCENE_CHANNELS | POSES_CHANNELS | JSON_CHANNELS
"""Every channel of the live view: key -> Foxglove topic."""

_NUMERIC = {"uint8": PackedElementFieldNumericType.Uint8, "int8": PackedElementFieldNumericType.Int8,
            "uint16": PackedElementFieldNumericType.Uint16, "int16": PackedElementFieldNumericType.Int16,
            "uint32": PackedElementFieldNumericType.Uint32, "int32": PackedElementFieldNumericType.Int32,
            "float32": PackedElementFieldNumericType.Float32, "float64": PackedElementFieldNumericType.Float64}
_IDENTITY = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)


_MAX_STAMP_NS = (2**32 - 1) * 1_000_000_000 + 999_999_999


def _stamp(ns: int) -> Timestamp:
    """A stamp in ns as a Foxglove Timestamp (unsigned seconds): one before the epoch is 0, one
    beyond 2**32 s the largest."""
    ns = min(max(int(ns), 0), _MAX_STAMP_NS)
    return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def _color(c: RGBA) -> Color:
    return Color(r=c[0], g=c[1], b=c[2], a=c[3])


def grid_message(layer: GridLayer) -> Grid:
    """A :class:`GridLayer` as a ``foxglove.Grid`` posed at the map's origin."""
    fields = [PackedElementField(name=n, offset=o, type=_NUMERIC[t])
              for (n, t), o in zip(layer.fields, layer.offsets())]
    pose = Pose(position=Vector3(x=layer.origin[0], y=layer.origin[1], z=0.0), orientation=_IDENTITY)
    return Grid(timestamp=_stamp(layer.stamp_ns), frame_id=layer.frame_id, pose=pose, column_count=layer.width,
                cell_size=Vector2(x=layer.resolution, y=layer.resolution), row_stride=layer.row_stride,
                cell_stride=layer.cell_stride, fields=fields, data=layer.data)


def line_primitive(line: Line) -> LinePrimitive:
    """A :class:`Line` as a ``foxglove.LinePrimitive`` (line strip, thickness in metres)."""
    return LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=Pose(position=Vector3(), orientation=_IDENTITY),
                         thickness=line.thickness, scale_invariant=False,
                         points=[Point3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in line.points],
                         color=_color(line.color))


def _line_entity(line: Line, frame_id: str) -> SceneEntity:
    return SceneEntity(timestamp=_stamp(line.stamp_ns), frame_id=frame_id, id=line.id, frame_locked=True,
                       metadata=[KeyValuePair(key="label", value=line.label),
                                 KeyValuePair(key="points", value=str(len(line.points)))],
                       lines=[line_primitive(line)])


def bind_warning(host: str) -> str | None:
    """The warning to log when the server binds ``host`` (None for a loopback address)."""
    if is_loopback(host):
        return None
    return (f"live view bound to {host}, not loopback: anyone who can reach this address can watch the "
            "mission (the Foxglove WebSocket server has no authentication)")


def port_in_use_message(host: str, port: int, exc: BaseException) -> str:
    """What to say when the live view cannot listen on ``host:port`` (names how to pick another port)."""
    return (f"port: cannot listen on {host}:{port} ({exc}); another live view (a second graph?) or program "
            "may hold it: pick another port with --viz-port N (scripts/launch_graph.py, the demo; 0 = any "
            "free port, printed) or the viz node's parameter port")


class _Listener(ServerListener):
    """``foxglove.websocket.ServerListener`` (its no-op defaults for everything else): re-log a
    channel's latest message to the client that subscribed."""

    def __init__(self, on_subscribe: Callable[[str, int], None]) -> None:
        self._on_subscribe = on_subscribe

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self._on_subscribe(str(channel.topic), int(client.id))


class LiveView:
    """The Foxglove WebSocket server of the live view and its channels.

    Args:
        host, port: where to listen (port 0 = any free port; :attr:`port` says which).
        logger: object with ``info``/``warning`` (a ROS logger), or None.
        name: the server name shown in Foxglove.
        allowed_origins: ``Origin`` values allowed besides loopback ones (``*``: any).

    Raises ``OSError`` when ``host:port`` cannot be bound (:func:`port_in_use_message` says it).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *, logger: Any = None,
                 name: str = "ird live view", allowed_origins: Any = DEFAULT_ALLOWED_ORIGINS) -> None:
        self.host = host
        self._lock = threading.Lock()
        self._latest: dict[str, Any] = {}  # topic -> last message logged (foxglove message or JSON dict)
        self._context = foxglove.Context()
        ctx = self._context
        self._channels: dict[str, Any] = {}
        for topic in GRID_CHANNELS.values():
            self._channels[topic] = GridChannel(topic, context=ctx)
        for topic in SCENE_CHANNELS.values():
            self._channels[topic] = SceneUpdateChannel(topic, context=ctx)
        for topic in POSES_CHANNELS.values():
            self._channels[topic] = PosesInFrameChannel(topic, context=ctx)
        for topic in JSON_CHANNELS.values():
            self._channels[topic] = foxglove.Channel(topic, message_encoding="json", context=ctx)
        warning = bind_warning(host)
        if warning is not None and logger is not None:
            logger.warning(warning)
        self._server = foxglove.start_server(name=name, host="127.0.0.1", port=0, context=ctx,
                                             server_listener=_Listener(self._relog))
        refused = None if logger is None else (lambda text: logger.warning(f"live view refused a client: {text}"))
        try:
            self._gate = Gate(host, int(port), int(self._server.port), allowed_origins=tuple(allowed_origins),
                              on_refused=refused)
        except OSError:
            self._server.stop()
            raise
        self.port = self._gate.port
        if logger is not None:
            logger.info(f"live view: Foxglove WebSocket on ws://{host}:{self.port}")

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def stop(self) -> None:
        """Stop the server (clients are disconnected)."""
        self._gate.stop()
        self._server.stop()

    # ------------------------------------------------------------------ logging

    def _log(self, topic: str, message: Any) -> None:
        if topic in JSON_CHANNELS.values():
            message = json.dumps(message).encode("utf-8")  # bytes: foxglove drops sink_id for a dict
        with self._lock:
            self._latest[topic] = message
            self._channels[topic].log(message, log_time=time.time_ns())

    def _relog(self, topic: str, client_id: int) -> None:
        """The latest message of ``topic`` to the client ``client_id`` only (its sink id)."""
        with self._lock:
            message = self._latest.get(topic)
            if message is not None:
                self._channels[topic].log(message, log_time=time.time_ns(), sink_id=client_id)

    def latest(self, key: str) -> Any:
        """The last message logged on channel ``key`` (of :data:`CHANNELS`; a JSON channel's as a
        dict), or None."""
        with self._lock:
            message = self._latest.get(CHANNELS[key])
        return json.loads(message) if key in JSON_CHANNELS and message is not None else message

    def show_grid(self, key: str, layer: GridLayer) -> None:
        """Show a grid on ``key`` (terrain, perceived or risk)."""
        self._log(GRID_CHANNELS[key], grid_message(layer))

    def show_plans(self, lines: list[Line], frame_id: str = "map") -> None:
        """Show the plans (one entity each; every current plan, so a late client sees them all)."""
        self._log(SCENE_CHANNELS["plans"], SceneUpdate(entities=[_line_entity(line, frame_id) for line in lines]))

    def show_rob(self, trail: RobTrail, resolution: float, frame_id: str = "map") -> None:
        """Show Rob: a cube at the trail's last pose and the trail (SceneUpdate), and the poses."""
        poses = trail.poses()
        if not poses:
            return
        x, y, yaw = poses[-1]
        side = 0.5 * float(resolution)
        orient = Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))
        cube = CubePrimitive(pose=Pose(position=Vector3(x=x, y=y, z=side / 2.0), orientation=orient),
                             size=Vector3(x=side, y=side, z=side), color=_color(hex_rgba(ROB_COLOR)))
        rob = SceneEntity(timestamp=_stamp(trail.stamp_ns), frame_id=frame_id, id="rob", frame_locked=True,
                          metadata=[KeyValuePair(key="label", value="Rob")], cubes=[cube])
        update = SceneUpdate(entities=[rob, _line_entity(trail.line(resolution), frame_id)])
        self._log(SCENE_CHANNELS["rob"], update)
        pose_list = [Pose(position=Vector3(x=px, y=py, z=0.0),
                          orientation=Quaternion(x=0.0, y=0.0, z=math.sin(a / 2.0), w=math.cos(a / 2.0)))
                     for px, py, a in poses]
        self._log(POSES_CHANNELS["trail"], PosesInFrame(timestamp=_stamp(trail.stamp_ns), frame_id=frame_id,
                                                        poses=pose_list))

    def show_json(self, key: str, data: dict[str, Any]) -> None:
        """Show a JSON dict on ``key`` (posterior, query or rob_status)."""
        self._log(JSON_CHANNELS[key], data)
