"""The live view's front door: a TCP gate that checks a WebSocket handshake's ``Host`` and ``Origin``
before the Foxglove server (foxglove-sdk) sees a byte of it. ROS-free, standard library only.

foxglove-sdk's WebSocket server accepts any ``Origin`` and any ``Host``: a web page open in a
browser on the machine could connect to ``ws://127.0.0.1:8766`` and read the mission (browsers
let any page open a WebSocket to loopback), and a DNS-rebinding page could do so under its own
host name. The SDK has no option to refuse them, so :class:`Gate` listens on the live view's
address instead and relays each accepted connection, byte for byte, to the SDK's server on an
ephemeral loopback port. The designer's web page (``ird_ros.web.server``) refuses the same two
with 403; the gate does too.

A request is refused (``HTTP/1.1 403 Forbidden``, JSON ``{"ok": false, "message": ...}``, then
closed) when:

- the gate listens on loopback and the ``Host`` header is not a loopback name or address
  (``localhost``, 127.0.0.0/8, ``::1``): DNS rebinding;
- an ``Origin`` header is present and :func:`origin_allowed` says no. Clients that are not web
  pages (the Foxglove and Lichtblick desktop apps' native connections, Python clients) send no
  ``Origin`` or one of the allowed ones.

A header larger than :data:`MAX_HEADER_BYTES` is answered 431, one that does not arrive within
:data:`HEADER_TIMEOUT` s is dropped; a repeated ``Host`` or ``Origin`` is refused (400).

Invariants: nothing reaches the SDK's server before the checks passed; one slow or hostile
connection never blocks another (asyncio, one task per connection, in the gate's own thread);
:meth:`Gate.stop` closes the listener and every relayed connection.
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
from typing import Callable, Sequence
from urllib.parse import urlsplit

from ird_ros.web.limits import MAX_HEADER_BYTES, host_of, is_loopback

__all__ = ["Gate", "origin_allowed", "check_handshake", "DEFAULT_ALLOWED_ORIGINS", "HEADER_TIMEOUT",
           "MAX_HEADER_BYTES"]

DEFAULT_ALLOWED_ORIGINS: tuple[str, ...] = ("file://", "https://app.foxglove.dev")
"""Origins allowed besides loopback ones: the desktop apps (Electron pages loaded from ``file://``)
and Foxglove's web app. The node's ``allowed_origins`` parameter replaces this list."""

HEADER_TIMEOUT = 10.0
"""Seconds a connection has to send its whole handshake header."""

_CHUNK = 64 * 1024


def origin_allowed(origin: str, allowed: Sequence[str]) -> bool:
    """Whether a handshake's ``Origin`` may connect: an ``http``/``https`` origin on a loopback
    host (any port), or one of ``allowed`` (compared without case and trailing ``/``; ``*``
    allows every origin)."""
    text = origin.strip().rstrip("/").lower()
    if "*" in allowed or text in {a.strip().rstrip("/").lower() for a in allowed}:
        return True
    try:
        parts = urlsplit(text)
        host = parts.hostname
    except ValueError:
        return False
    return parts.scheme in ("http", "https") and host is not None and is_loopback(host)


def check_handshake(head: bytes, *, loopback_only: bool, allowed_origins: Sequence[str]) -> tuple[int, str] | None:
    """``None`` if the HTTP request header ``head`` may pass, else ``(status, message)``; the
    message starts with the refused header's name."""
    lines = head.decode("latin-1").split("\r\n")
    fields: dict[str, list[str]] = {}
    for line in lines[1:]:
        if not line:
            continue
        name, sep, value = line.partition(":")
        if not sep:
            return 400, f"header: malformed line {line[:80]!r}"
        fields.setdefault(name.strip().lower(), []).append(value.strip())
    for name in ("host", "origin"):
        if len(fields.get(name, [])) > 1:
            return 400, f"{name.capitalize()}: the header is repeated"
    host = (fields.get("host") or [""])[0]
    if loopback_only and not is_loopback(host_of(host)):
        return 403, f"Host: {host[:200]!r} is not a loopback name or address (the live view is bound to loopback)"
    origin = fields.get("origin")
    if origin is not None and not origin_allowed(origin[0], allowed_origins):
        return 403, (f"Origin: {origin[0][:200]!r} is not allowed (loopback origins and "
                     f"{', '.join(allowed_origins) or 'no other'}; the viz node's parameter allowed_origins)")
    return None


def _reply(status: int, message: str) -> bytes:
    reason = {400: "Bad Request", 403: "Forbidden", 431: "Request Header Fields Too Large"}[status]
    body = json.dumps({"ok": False, "message": message}).encode()
    return (f"HTTP/1.1 {status} {reason}\r\nContent-Type: application/json\r\nContent-Length: {len(body)}\r\n"
            "Connection: close\r\n\r\n").encode() + body


class Gate:
    """Listens on ``host:port`` (0 = any free port; :attr:`port` says which) and relays each
    connection whose handshake passes :func:`check_handshake` to ``127.0.0.1:upstream_port``.

    Raises ``OSError`` from the constructor when the address cannot be bound (a port in use).
    ``on_refused(message)`` is called (from the gate's thread) for every refused handshake.
    """

    def __init__(self, host: str, port: int, upstream_port: int, *, allowed_origins: Sequence[str],
                 on_refused: Callable[[str], None] | None = None) -> None:
        self.host = host
        self.allowed_origins = tuple(allowed_origins)
        self.loopback_only = is_loopback(host)
        self._upstream_port = int(upstream_port)
        self._on_refused = on_refused
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
        self._sock = socket.create_server((host, int(port)), family=family)
        self.port = int(self._sock.getsockname()[1])
        self._loop = asyncio.new_event_loop()
        self._writers: set[asyncio.StreamWriter] = set()
        self._server: asyncio.AbstractServer | None = None
        started = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(started,), name="live-view-gate", daemon=True)
        self._thread.start()
        started.wait()

    def _run(self, started: threading.Event) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._server = self._loop.run_until_complete(
                asyncio.start_server(self._handle, sock=self._sock, limit=MAX_HEADER_BYTES))
        finally:
            started.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.close()

    def stop(self) -> None:
        """Close the listener and every connection; wait for the gate's thread."""
        if not self._thread.is_alive():
            return

        async def close() -> None:
            if self._server is not None:
                self._server.close()
            for writer in list(self._writers):
                writer.close()
            tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            self._loop.stop()

        asyncio.run_coroutine_threadsafe(close(), self._loop)
        self._thread.join(timeout=5)

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._writers.add(writer)
        try:
            try:
                head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEADER_TIMEOUT)
            except asyncio.LimitOverrunError:
                await self._refuse(writer, 431, f"header: larger than {MAX_HEADER_BYTES} bytes")
                return
            except (asyncio.IncompleteReadError, asyncio.TimeoutError, ConnectionError, OSError):
                return
            refusal = check_handshake(head, loopback_only=self.loopback_only, allowed_origins=self.allowed_origins)
            if refusal is not None:
                await self._refuse(writer, *refusal)
                return
            try:
                up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self._upstream_port)
            except OSError:
                return
            self._writers.add(up_writer)
            try:
                up_writer.write(head)
                await self._relay(reader, writer, up_reader, up_writer)
            finally:
                self._writers.discard(up_writer)
                up_writer.close()
        finally:
            self._writers.discard(writer)
            writer.close()

    async def _refuse(self, writer: asyncio.StreamWriter, status: int, message: str) -> None:
        if self._on_refused is not None:
            self._on_refused(message)
        try:
            writer.write(_reply(status, message))
            await writer.drain()
        except (ConnectionError, OSError):
            pass

    @staticmethod
    async def _relay(reader: asyncio.StreamReader, writer: asyncio.StreamWriter,
                     up_reader: asyncio.StreamReader, up_writer: asyncio.StreamWriter) -> None:
        async def pipe(src: asyncio.StreamReader, dst: asyncio.StreamWriter) -> None:
            try:
                while data := await src.read(_CHUNK):
                    dst.write(data)
                    await dst.drain()
            except (ConnectionError, OSError):
                pass

        tasks = [asyncio.ensure_future(pipe(reader, up_writer)), asyncio.ensure_future(pipe(up_reader, writer))]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
