"""A plain Foxglove WebSocket client for the live-view tests, with its own protobuf decoder.

The client speaks the protocol directly (``websocket-client``, subprotocol ``foxglove.sdk.v1``):
it reads ``serverInfo`` and ``advertise``, subscribes to every advertised channel, and decodes
each binary ``messageData`` (opcode 0x01, uint32 subscription id, uint64 log time, payload) with
the schema the server advertised: protobuf channels carry a base64 ``FileDescriptorSet``, which
:func:`descriptor_pool` reads (protobuf wire format by hand: ``google.protobuf`` is not in the
venv), JSON channels are JSON. A reader thread collects everything; tests wait on a condition
(no sleeps).
"""

from __future__ import annotations

import base64
import json
import struct
import threading
from typing import Any, Callable

SUBPROTOCOL = "foxglove.sdk.v1"

# ---------------------------------------------------------------------------- protobuf wire format

_VARINT_TYPES = {3, 4, 5, 8, 13, 14, 17, 18}  # int64 uint64 int32 bool uint32 enum sint32 sint64
_FIXED64 = {1: "<d", 6: "<Q", 16: "<q"}
_FIXED32 = {2: "<f", 7: "<I", 15: "<i"}


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    shift = value = 0
    while True:
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if not b & 0x80:
            return value, i


def wire_fields(buf: bytes) -> list[tuple[int, int, Any]]:
    """``(field number, wire type, raw value)`` of every field of a protobuf message, in order."""
    out, i = [], 0
    while i < len(buf):
        key, i = _varint(buf, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(buf, i)
        elif wire == 1:
            value, i = buf[i:i + 8], i + 8
        elif wire == 2:
            n, i = _varint(buf, i)
            value, i = buf[i:i + n], i + n
        elif wire == 5:
            value, i = buf[i:i + 4], i + 4
        else:
            raise ValueError(f"unsupported wire type {wire}")
        out.append((number, wire, value))
    return out


def _strings(fields: list, number: int) -> list[str]:
    return [v.decode() for n, _, v in fields if n == number]


def descriptor_pool(file_descriptor_set: bytes) -> dict[str, dict[int, tuple[str, int, bool, str]]]:
    """``{".pkg.Message": {field number: (name, type, repeated, type_name)}}`` of a FileDescriptorSet."""
    pool: dict[str, dict[int, tuple[str, int, bool, str]]] = {}

    def message(buf: bytes, scope: str) -> None:
        fields = wire_fields(buf)
        full = f"{scope}.{_strings(fields, 1)[0]}"
        table = pool.setdefault(full, {})
        for n, _, v in fields:
            if n == 2:  # FieldDescriptorProto: 1 name, 3 number, 4 label, 5 type, 6 type_name
                f = wire_fields(v)
                ints = {k: val for k, w, val in f if w == 0}
                type_name = (_strings(f, 6) or [""])[0]
                table[ints[3]] = (_strings(f, 1)[0], ints[5], ints.get(4) == 3, type_name)
            elif n == 3:  # nested DescriptorProto
                message(v, full)

    for n, _, file_buf in wire_fields(file_descriptor_set):
        if n != 1:
            continue
        f = wire_fields(file_buf)
        package = (_strings(f, 2) or [""])[0]
        for k, _, v in f:
            if k == 4:
                message(v, f".{package}" if package else "")
    return pool


def _scalar(kind: int, wire: int, raw: Any) -> Any:
    if kind in _VARINT_TYPES:
        if kind == 8:
            return bool(raw)
        if kind in (17, 18):
            return (raw >> 1) ^ -(raw & 1)
        if kind in (3, 5) and raw >= 1 << 63:
            return raw - (1 << 64)
        return raw
    if kind in _FIXED64:
        return struct.unpack(_FIXED64[kind], raw)[0]
    if kind in _FIXED32:
        return struct.unpack(_FIXED32[kind], raw)[0]
    if kind == 9:
        return raw.decode()
    return bytes(raw)  # 12 bytes


def _packed(kind: int, raw: bytes) -> list[Any]:
    if kind in _FIXED64:
        return list(struct.unpack(f"<{len(raw) // 8}{_FIXED64[kind][1]}", raw))
    if kind in _FIXED32:
        return list(struct.unpack(f"<{len(raw) // 4}{_FIXED32[kind][1]}", raw))
    out, i = [], 0
    while i < len(raw):
        v, i = _varint(raw, i)
        out.append(_scalar(kind, 0, v))
    return out


def decode(pool: dict, type_name: str, buf: bytes) -> dict[str, Any]:
    """A protobuf message as a dict: every field of the schema (proto3 defaults when absent,
    None for an absent message, lists for repeated fields)."""
    table = pool[type_name]
    out: dict[str, Any] = {}
    for name, kind, repeated, sub in table.values():
        out[name] = [] if repeated else None if kind == 11 else "" if kind == 9 else b"" if kind == 12 else \
            False if kind == 8 else 0
    for number, wire, raw in wire_fields(buf):
        if number not in table:
            continue
        name, kind, repeated, sub = table[number]
        if kind == 11:
            value: Any = decode(pool, sub, raw)
        elif repeated and wire == 2 and kind not in (9, 12):
            out[name].extend(_packed(kind, raw))
            continue
        else:
            value = _scalar(kind, wire, raw)
        if repeated:
            out[name].append(value)
        else:
            out[name] = value
    return out


# ---------------------------------------------------------------------------- the client


class FoxgloveClient:
    """Connects, subscribes to every advertised channel, decodes and keeps every message.

    Attributes:
        server_info: the serverInfo JSON.
        channels: channel id -> the advertise entry.
        messages: topic -> decoded messages in arrival order (dicts).
    """

    def __init__(self, url: str, *, timeout: float = 10.0) -> None:
        import websocket

        self.ws = websocket.create_connection(url, subprotocols=[SUBPROTOCOL], timeout=timeout)
        self.subprotocol = self.ws.subprotocol
        self.server_info: dict[str, Any] | None = None
        self.channels: dict[int, dict[str, Any]] = {}
        self.messages: dict[str, list[Any]] = {}
        self.errors: list[str] = []
        self._subs: dict[int, int] = {}  # subscription id -> channel id
        self._pools: dict[int, dict] = {}
        self._cond = threading.Condition()
        self._closed = False
        self.ws.settimeout(None)
        self._thread = threading.Thread(target=self._read, name="foxglove-client", daemon=True)
        self._thread.start()

    def _read(self) -> None:
        import websocket

        while True:
            try:
                data = self.ws.recv()
            except (websocket.WebSocketException, OSError) as exc:
                with self._cond:
                    if not self._closed:
                        self.errors.append(f"connection: {exc!r}")
                    self._closed = True
                    self._cond.notify_all()
                return
            try:
                self._handle(data)
            except Exception as exc:  # noqa: BLE001 - reported to the test, which fails on it
                with self._cond:
                    self.errors.append(f"{type(exc).__name__}: {exc}")
                    self._cond.notify_all()

    def _handle(self, data: str | bytes) -> None:
        if isinstance(data, str):
            msg = json.loads(data)
            with self._cond:
                if msg["op"] == "serverInfo":
                    self.server_info = msg
                elif msg["op"] == "advertise":
                    new = [c for c in msg["channels"] if c["id"] not in self.channels]
                    for c in new:
                        self.channels[c["id"]] = c
                        if c["encoding"] == "protobuf":
                            self._pools[c["id"]] = descriptor_pool(base64.b64decode(c["schema"]))
                        self._subs[len(self._subs) + 1] = c["id"]
                    fresh = {c["id"] for c in new}
                    subs = [{"id": s, "channelId": cid} for s, cid in self._subs.items() if cid in fresh]
                    if subs:
                        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                self._cond.notify_all()
            return
        if data[0] != 0x01:
            return  # time, service responses...: not used
        sub_id, _log_time = struct.unpack_from("<IQ", data, 1)
        payload = data[13:]
        with self._cond:
            channel = self.channels[self._subs[sub_id]]
        if channel["encoding"] == "json":
            value: Any = json.loads(payload)
        else:
            value = decode(self._pools[channel["id"]], "." + channel["schemaName"], payload)
        with self._cond:
            self.messages.setdefault(channel["topic"], []).append(value)
            self._cond.notify_all()

    def wait_for(self, predicate: Callable[["FoxgloveClient"], bool], timeout: float, what: str) -> None:
        """Wait until ``predicate(self)`` holds (checked on every received message); AssertionError
        naming ``what`` (and the topics seen) after ``timeout`` s."""
        with self._cond:
            ok = self._cond.wait_for(lambda: predicate(self) or bool(self.errors) or self._closed, timeout)
            assert not self.errors, self.errors
            assert ok and predicate(self), f"timeout waiting for {what}; topics seen: " \
                f"{ {t: len(m) for t, m in self.messages.items()} }"

    def topics(self) -> dict[str, dict[str, Any]]:
        with self._cond:
            return {c["topic"]: c for c in self.channels.values()}

    def close(self) -> None:
        with self._cond:
            self._closed = True
        self.ws.close()
        self._thread.join(timeout=5)
