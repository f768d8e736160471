"""A tolerant reader of MCAP files (no ROS, no rosbags): every complete record of a possibly
truncated or unindexed file, for :func:`ird_ros.bags.repair.reindex`.

:class:`McapScan` is a streaming scan that stops at the first incomplete or inconsistent record,
so what it returns is always a prefix of the recorded messages; complete message records inside
a cut-off uncompressed chunk count too. Record layout: the MCAP specification (opcode byte,
little-endian uint64 length, body).
"""

from __future__ import annotations

import mmap
import struct
import sys
import zlib
from dataclasses import dataclass, field
from typing import Iterator, Union

__all__ = ["MAGIC", "OP_HEADER", "OP_FOOTER", "OP_SCHEMA", "OP_CHANNEL", "OP_MESSAGE", "OP_CHUNK", "OP_STATISTICS",
           "OP_DATA_END", "FOOTER_LEN", "McapSchema", "McapChannel", "McapMessage", "McapScan",
           "summary_message_count"]

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_STATISTICS, OP_DATA_END = 0x0B, 0x0F
FOOTER_LEN = 20
"""Length of a Footer record's body."""


@dataclass(frozen=True)
class McapSchema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class McapChannel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class McapMessage:
    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


McapItem = Union[McapSchema, McapChannel, McapMessage]


class _Truncated(Exception):
    """The data ends inside a record."""


class _Corrupt(Exception):
    """A complete record that cannot be right (bad opcode, length, CRC, unknown id)."""


class _Fields:
    """Little-endian field reader over ``buf[pos:end]`` that raises ``_Corrupt`` on overrun."""

    def __init__(self, buf: memoryview, pos: int, end: int) -> None:
        self.buf, self.pos, self.end = buf, pos, end

    def take(self, n: int) -> memoryview:
        if n < 0 or self.pos + n > self.end:
            raise _Corrupt(f"field overruns its record at byte {self.pos}")
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def unpack(self, fmt: str) -> tuple[int, ...]:
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))

    def string(self) -> str:
        try:
            return bytes(self.take(self.unpack("<I")[0])).decode()
        except UnicodeDecodeError as exc:
            raise _Corrupt(f"string is not UTF-8 at byte {self.pos}") from exc

    def rest(self) -> bytes:
        return bytes(self.take(self.end - self.pos))


def _frames(buf: memoryview, pos: int, stop: int) -> Iterator[tuple[int, int, int]]:
    """``(opcode, body_start, body_end)`` of consecutive records in ``buf[pos:stop]``;
    ``_Truncated`` when ``stop`` falls inside one."""
    while pos < stop:
        if pos + 9 > stop:
            raise _Truncated(f"record header cut off at byte {pos}")
        op = buf[pos]
        (length,) = struct.unpack_from("<Q", buf, pos + 1)
        if op == 0:
            raise _Corrupt(f"opcode 0 at byte {pos}")
        body = pos + 9
        if body + length > stop:
            raise _Truncated(f"record 0x{op:02x} at byte {pos} cut off ({length} bytes announced, {stop - body} there)")
        yield op, body, body + length
        pos = body + length


def _decompress(kind: str, data: bytes) -> bytes:
    if kind == "":
        return data
    if kind == "zstd":
        if sys.version_info >= (3, 14):
            from compression import zstd
        else:
            from backports import zstd
        return zstd.decompress(data)
    if kind == "lz4":
        import lz4.frame  # optional: rosbags never writes lz4

        return lz4.frame.decompress(data)
    raise _Corrupt(f"unsupported chunk compression {kind!r}")


@dataclass
class McapScan:
    """Every complete, consistent record of an MCAP file's data section, in file order.

    Iterate to get the schemas, channels and messages; afterwards ``complete`` says whether
    the data section ended properly (DataEnd or Footer), ``stop_reason`` why the scan ended
    otherwise, ``valid_bytes`` how much of the file was understood.
    """

    data: bytes | mmap.mmap
    schemas: dict[int, McapSchema] = field(default_factory=dict)
    channels: dict[int, McapChannel] = field(default_factory=dict)
    complete: bool = False
    stop_reason: str = ""
    valid_bytes: int = 0

    def __iter__(self) -> Iterator[McapItem]:
        buf = memoryview(self.data)
        if len(buf) < len(MAGIC) or bytes(buf[:len(MAGIC)]) != MAGIC:
            self.stop_reason = "no MCAP magic at the start of the file"
            return
        self.valid_bytes = len(MAGIC)
        try:
            for op, body, end in _frames(buf, len(MAGIC), len(buf)):
                if op in (OP_DATA_END, OP_FOOTER):
                    self.complete = True
                    return
                if op == OP_CHUNK:
                    yield from self._chunk(buf, body, end, end)
                elif op in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
                    yield self._record(buf, op, body, end)
                self.valid_bytes = end
            self.stop_reason = f"file ends after {len(buf)} bytes without DataEnd/Footer"
        except _Truncated as exc:
            self.stop_reason = str(exc)
            start = self.valid_bytes
            if buf[start] == OP_CHUNK:  # a cut-off chunk: its complete records still count
                try:
                    yield from self._chunk(buf, start + 9, struct.unpack_from("<Q", buf, start + 1)[0] + start + 9, len(buf))
                except (_Truncated, _Corrupt, struct.error):
                    pass
        except (_Corrupt, struct.error) as exc:
            self.stop_reason = f"corrupt data: {exc}"

    def _chunk(self, buf: memoryview, body: int, end: int, available: int) -> Iterator[McapItem]:
        head = _Fields(buf, body, min(end, available))
        _start, _end, size, crc = head.unpack("<QQQI")
        kind = head.string()
        (length,) = head.unpack("<Q")
        records_end = head.pos + length
        if records_end > end:
            raise _Corrupt(f"chunk at byte {body - 9} announces more records than it holds")
        if records_end > available:  # cut off: only an uncompressed chunk can be read in part
            if kind != "":
                raise _Truncated("compressed chunk cut off")
            inner, stop = buf, available
            pos = head.pos
        else:
            raw = bytes(buf[head.pos:records_end]) if kind else None
            if raw is not None:
                try:
                    decoded = _decompress(kind, raw)
                except _Corrupt:
                    raise
                except Exception as exc:  # noqa: BLE001 - any codec error = a damaged chunk
                    raise _Corrupt(f"chunk does not decompress: {exc}") from exc
                inner, pos, stop = memoryview(decoded), 0, len(decoded)
            else:
                inner, pos, stop = buf, head.pos, records_end
            if len(inner[pos:stop]) != size:
                raise _Corrupt(f"chunk at byte {body - 9}: {len(inner[pos:stop])} bytes, {size} announced")
            if crc and zlib.crc32(inner[pos:stop]) != crc:
                raise _Corrupt(f"chunk at byte {body - 9}: CRC mismatch")
        try:
            for op, rbody, rend in _frames(inner, pos, stop):
                if op not in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
                    raise _Corrupt(f"record 0x{op:02x} inside a chunk")
                yield self._record(inner, op, rbody, rend)
        except _Truncated as exc:
            if stop == available and records_end > available:
                raise  # the file ends inside this chunk: the expected end of a partial read
            raise _Corrupt(f"chunk at byte {body - 9}: {exc}") from exc

    def _record(self, buf: memoryview, op: int, body: int, end: int) -> McapItem:
        rec = _Fields(buf, body, end)
        if op == OP_SCHEMA:
            (sid,) = rec.unpack("<H")
            schema = McapSchema(sid, rec.string(), rec.string(), bytes(rec.take(rec.unpack("<I")[0])))
            self.schemas[sid] = schema
            return schema
        if op == OP_CHANNEL:
            cid, sid = rec.unpack("<HH")
            topic, encoding = rec.string(), rec.string()
            meta = _Fields(buf, rec.pos + 4, rec.pos + 4 + rec.unpack("<I")[0])
            if meta.end > end:
                raise _Corrupt(f"channel {cid}: metadata overruns the record")
            pairs: dict[str, str] = {}
            while meta.pos < meta.end:
                key = meta.string()
                pairs[key] = meta.string()
            if sid and sid not in self.schemas:
                raise _Corrupt(f"channel {cid} ({topic}) names unknown schema {sid}")
            channel = McapChannel(cid, sid, topic, encoding, pairs)
            self.channels[cid] = channel
            return channel
        cid, seq, log_time, pub_time = rec.unpack("<HIQQ")
        if cid not in self.channels:
            raise _Corrupt(f"message on unknown channel {cid}")
        return McapMessage(cid, seq, log_time, pub_time, rec.rest())


def summary_message_count(buf: bytes | mmap.mmap) -> int | None:
    """The Statistics message count of a finished MCAP (footer with a summary), else None."""
    footer = len(buf) - len(MAGIC) - 9 - FOOTER_LEN
    if footer < len(MAGIC) or buf[-len(MAGIC):] != MAGIC or buf[footer] != OP_FOOTER:
        return None
    (summary_start,) = struct.unpack_from("<Q", buf, footer + 9)
    if not len(MAGIC) <= summary_start < footer:
        return None
    try:
        for op, body, _end in _frames(memoryview(buf), summary_start, footer):
            if op == OP_STATISTICS:
                return int(struct.unpack_from("<Q", buf, body)[0])
    except (_Truncated, _Corrupt, struct.error):
        return None
    return None
