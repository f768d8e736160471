"""What a request to the designer page's server (``ird_ros.web.server``) may be (ROS-free): its caps
(sizes, nesting, timeouts), its ``Host`` (``is_loopback``, ``host_of``) and an answer's body
(``parse_answer``).

A request body is capped at ``MAX_BODY_BYTES`` (64 KiB; answered 413 naming the limit: a body
announced up to ``MAX_BODY_READ_BYTES`` is read to its end and dropped first, so the client gets
the answer rather than a reset, one announced beyond it is refused from its header), a JSON body's
nesting at ``MAX_JSON_DEPTH`` (400 naming the limit; measured by ``json_depth`` in one pass,
without recursion, before ``json.loads`` could exhaust the stack), headers at
``MAX_HEADER_BYTES``, a WebSocket message at ``MAX_WS_MESSAGE_BYTES``. A connection that sends
no complete request header for ``IDLE_TIMEOUT`` s (a slowloris client, or an idle keep-alive
connection), or whose body does not arrive within ``BODY_TIMEOUT`` s, is closed; a WebSocket is
pinged every ``WS_PING_INTERVAL`` s and closed when no pong came within ``WS_PING_TIMEOUT`` s.
At most ``MAX_SOCKETS`` WebSockets (pages) are open at once; one more is closed with code
``WS_CLOSE_TRY_AGAIN`` (1013) and a reason naming the limit.
"""

from __future__ import annotations

import ipaddress
import json

__all__ = [
    "is_loopback",
    "host_of",
    "parse_answer",
    "MAX_BODY_BYTES",
    "MAX_BODY_READ_BYTES",
    "MAX_JSON_DEPTH",
    "MAX_HEADER_BYTES",
    "MAX_WS_MESSAGE_BYTES",
    "IDLE_TIMEOUT",
    "BODY_TIMEOUT",
    "WS_PING_INTERVAL",
    "WS_PING_TIMEOUT",
    "MAX_SOCKETS",
    "WS_CLOSE_TRY_AGAIN",
    "json_depth",
    "check_json_depth",
]

MAX_BODY_BYTES = 64 * 1024
MAX_BODY_READ_BYTES = 16 * MAX_BODY_BYTES
MAX_JSON_DEPTH = 16
MAX_HEADER_BYTES = 16 * 1024
MAX_WS_MESSAGE_BYTES = 64 * 1024
IDLE_TIMEOUT = 30.0
BODY_TIMEOUT = 30.0
WS_PING_INTERVAL = 20.0
WS_PING_TIMEOUT = 30.0
MAX_SOCKETS = 16
WS_CLOSE_TRY_AGAIN = 1013  # RFC 6455 "Try Again Later": a page beyond MAX_SOCKETS

_OPEN = frozenset(b"[{")
_CLOSE = frozenset(b"]}")
_QUOTE = ord('"')
_BACKSLASH = ord("\\")


def json_depth(body: bytes, stop_above: int | None = None) -> int:
    """The deepest nesting of arrays and objects in JSON text ``body`` (0 for a scalar).

    One pass over the bytes, brackets inside strings skipped (escapes honoured), no recursion;
    with ``stop_above`` it returns as soon as the depth exceeds it. Malformed text gets a number
    too (``json.loads`` refuses it afterwards).
    """
    depth = deepest = 0
    in_string = escaped = False
    for byte in body:
        if in_string:
            if escaped:
                escaped = False
            elif byte == _BACKSLASH:
                escaped = True
            elif byte == _QUOTE:
                in_string = False
        elif byte == _QUOTE:
            in_string = True
        elif byte in _OPEN:
            depth += 1
            if depth > deepest:
                deepest = depth
                if stop_above is not None and deepest > stop_above:
                    return deepest
        elif byte in _CLOSE:
            depth = max(depth - 1, 0)
    return deepest


def check_json_depth(body: bytes, limit: int = MAX_JSON_DEPTH) -> None:
    """``ValueError`` (``body: ...``, naming ``limit``) when ``body`` nests deeper than ``limit``."""
    if json_depth(body, stop_above=limit) > limit:
        raise ValueError(f"body: JSON nested deeper than {limit} levels (the limit is {limit})")


_LOOPBACK_NAMES = frozenset({"localhost", "localhost.localdomain"})


def is_loopback(host: str) -> bool:
    """True for a loopback host name or address (127.0.0.0/8, ::1, localhost)."""
    name = host.strip().strip("[]").lower()
    if name in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def host_of(header: str) -> str:
    """The host part of an HTTP ``Host`` header (``name``, ``name:port``, ``[v6]:port``)."""
    if header.startswith("["):
        return header[1 : header.find("]")] if "]" in header else header
    return header.rsplit(":", 1)[0] if header.count(":") == 1 else header


def parse_answer(body: bytes) -> tuple[int, int]:
    """``(query_id, chosen)`` of a JSON answer body; ValueError naming the bad field (or the limit)."""
    check_json_depth(body)
    try:
        data = json.loads(body or b"null")
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise ValueError(f"body: not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError('body: expected a JSON object {"query_id": int, "chosen": int}')
    values = []
    for field in ("query_id", "chosen"):
        value = data.get(field)
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{field}: expected an integer, got {value!r}")
        if not 0 <= value < 2**32:
            raise ValueError(f"{field}: {value} is out of range (0..2^32-1)")
        values.append(value)
    return values[0], values[1]
