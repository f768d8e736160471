"""The designer's web page: a person answers the robot's queries in a browser (ROS-free).

``WebDesigner`` serves one page (``ird_ros/web/static/``: HTML, JS, CSS, no external assets) from an
HTTP server (Tornado) running in its own thread. The designer node (``ird_ros.nodes.designer``,
``mode: web``) owns every ROS interface and feeds this object plain dicts::

    web = WebDesigner("127.0.0.1", 8765, on_answer, logger=node.get_logger())
    web.start()                        # listening when it returns; web.url has the real port
    web.show_world(world)              # terrain to draw (a new world makes older queries stale)
    web.show_train_world(train_world)  # the training map (a proxies query's options are drawn on it)
    web.show_query(record)             # a new open query
    web.show_answer(record)            # a query got answered (by anyone)
    web.show_posterior(posterior, risk_map)
    web.show_mission(mission)          # how the last drive ended (Rob's final status, the goal's outcome)
    web.finish("mission finished")     # optional: the page shows a finished state, no more answers
    web.stop()                         # sends the end state ("graph stopped") to every open page first

The dict layouts are documented in the ``show_*`` docstrings (built by
:func:`ird_ros.bags.rounds.record_dict` and ``ird_ros.nodes.designer``'s ``*_dict``; the
conversation is docs/spec.md section 7). A query's ``kind`` says what the designer picks: "paths"
(options are paths on the test map: "Which path do you prefer?") or "proxies" (options are proxy
rewards, ``option_proxies`` q lists of weights named by ``proxy_feature_names``, each drawn as its
plan on the training map: "Which reward would you have written for the training world?"); a
click is an option index for both. Every ``show_*`` is thread-safe and non-blocking: it updates the state
under a lock and schedules a push of the new state to every open page over a WebSocket, so the
page updates without a reload.

Routes:

- ``GET /``: the page; ``GET /static/<file>``: its assets.
- ``GET /state``: the state as JSON (what the page renders; tests read it).
- ``POST /answer`` with JSON ``{"query_id": int, "chosen": int}``: a click. The server checks it
  first (well-formed, a known query of the current world, not answered, not already being
  answered, ``chosen`` in range) and refuses with a message that the page shows; only then it
  calls ``on_answer(query_id, chosen) -> (ok, message)`` in a worker thread (it blocks while
  the posterior is re-sampled). An accepted answer is answered with the page's thank-you line
  (``page_state.thank_you``: the option's letter and the question, no sampler statistics; the
  callback's message is logged); a refusal with the callback's message. Only JSON bodies are
  accepted, so a plain HTML form on another site cannot submit an answer.
- ``GET /ws``: WebSocket; the server sends the whole state after every change.

End: ``finish(text)`` and ``stop()`` set the state's ``finished`` (why the page gets no more
questions; ``stop`` uses "graph stopped" unless finished before) and push it to every open page
before the sockets close, so the page shows a finished state instead of reconnecting; a page that
loses its server without that (a killed process) gives up after a few reconnects and says the
graph is gone (``static/app.js``). Options are letters (A, B, ...) in every message.

Caps (``ird_ros.web.limits``): a body over ``max_body`` (64 KiB) is answered 413 (read and dropped
up to 16 times that, refused from its header beyond), JSON nested over
16 levels 400, both naming the limit; no complete header for ``idle_timeout`` s (slowloris) or no
body for ``body_timeout`` s: disconnected; WebSocket messages capped and pinged. Every error, a
handler's exception too, is a JSON ``{"ok": false, "message": ...}`` answer; the server keeps serving.
At most ``max_sockets`` pages (16) are open at once: one more is closed with 1013 and a reason
naming the limit; a page that reads slowly or not at all is sent only the latest state when it
catches up (one message in flight per page), so it cannot make the server queue every state.

Why Tornado: HTTP server, WebSockets and static files in one well-kept library with no
dependencies of its own, and it is already in the venv (a dependency of Dask's distributed).

Longer than 450 lines: the handlers, the per-page sender and ``WebDesigner`` share the server's
state, lock and event loop; the caps and the page's state already live in ``limits`` and ``page_state``.

Binding: 127.0.0.1 by default. Another host is allowed (a designer on another machine) with a
logged warning: the page has no authentication. While bound to loopback, requests whose
``Host`` header is not a loopback name are refused (a web page elsewhere cannot reach the
server through DNS rebinding).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import copy
import json
import logging
import threading
from pathlib import Path
from typing import Any, Callable

import tornado.httpserver
import tornado.netutil
import tornado.web
import tornado.websocket

from ird_ros.resources import web_static_dir
from ird_ros.web import limits
from ird_ros.web.limits import host_of, is_loopback, parse_answer
from ird_ros.web.page_state import PageState, thank_you

__all__ = ["WebDesigner", "OnAnswer", "WEB_DIR", "is_loopback"]

#: Static assets of the page: only these files are served (never the server's own code).
WEB_DIR = web_static_dir()  # package data (ird_ros.resources)

#: The node's answer callback: ``(query_id, chosen) -> (ok, message)``; blocks until answered.
OnAnswer = Callable[[int, int], "tuple[bool, str]"]

def _check_host(handler: Any) -> None:
    """Refuse a request whose Host is not a loopback name while bound to loopback."""
    if handler.web.loopback_only and not is_loopback(host_of(handler.request.host)):
        raise tornado.web.HTTPError(403, reason="Host not allowed")


class _Handler(tornado.web.RequestHandler):
    """Base handler: the designer object, and the loopback Host check."""

    def initialize(self, web: "WebDesigner") -> None:
        self.web = web

    def prepare(self) -> None:
        _check_host(self)

    def set_default_headers(self) -> None:
        self.set_header("Cache-Control", "no-store")
        self.set_header("X-Content-Type-Options", "nosniff")

    def _reply(self, status: int, ok: bool, message: str) -> None:
        self.set_status(status)
        self.set_header("Content-Type", "application/json")
        self.write(json.dumps({"ok": ok, "message": message}))

    def write_error(self, status_code: int, **kwargs: Any) -> None:
        """Every error as JSON ``{"ok": false, "message": ...}`` (a handler's exception included)."""
        exc = kwargs.get("exc_info", (None, None, None))[1]
        message = (exc.log_message if isinstance(exc, tornado.web.HTTPError) else None) or self._reason
        if exc is not None and not isinstance(exc, tornado.web.HTTPError):
            message = f"internal error: {type(exc).__name__} (the server keeps serving)"
            self.web.log.error(f"designer web page: {self.request.method} {self.request.path} raised {exc!r}")
        self._reply(status_code, False, message)
        self.finish()


class _PageHandler(_Handler):
    def get(self) -> None:
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.write((WEB_DIR / "index.html").read_bytes())


class _StateHandler(_Handler):
    def get(self) -> None:
        self.set_header("Content-Type", "application/json")
        self.write(self.web.state_json())


@tornado.web.stream_request_body
class _AnswerHandler(_Handler):
    """``POST /answer``; the body is streamed in and kept only up to ``max_body`` bytes, then
    answered 413 (read to its end first, so the client gets the answer, not a reset)."""

    def check_xsrf_cookie(self) -> None:
        # Cross-site forms cannot send JSON; the Content-Type check below replaces a cookie.
        return None

    def prepare(self) -> None:
        super().prepare()
        self._chunks: list[bytes] = []
        self._size = 0
        length = self.request.headers.get("Content-Length", "")
        if length.isdigit() and int(length) > self.web.max_read:  # not worth reading: refuse now
            raise tornado.web.HTTPError(413, self._too_large())

    def _too_large(self) -> str:
        return f"body: larger than {self.web.max_body} bytes (the limit is {self.web.max_body // 1024} KiB)"

    def data_received(self, chunk: bytes) -> None:
        self._size += len(chunk)
        if self._size <= self.web.max_body:
            self._chunks.append(chunk)

    async def post(self) -> None:
        if self._size > self.web.max_body:
            return self._reply(413, False, self._too_large())
        if self.request.headers.get("Content-Type", "").split(";")[0].strip() != "application/json":
            return self._reply(415, False, "Content-Type: answers must be sent as application/json")
        try:
            query_id, chosen = parse_answer(b"".join(self._chunks))
        except ValueError as exc:
            return self._reply(400, False, str(exc))
        status, ok, message = await self.web.answer(query_id, chosen)
        self._reply(status, ok, message)


class _SocketHandler(tornado.websocket.WebSocketHandler):
    """One open page. It is sent the whole state after every change, at most one message in flight:
    while a write waits for a page that reads slowly (or not at all), newer states only mark it
    dirty and the latest one follows when the write is done. So a page that never reads holds
    two states in the server at most, not every state since it stopped, and the write a close
    fails is retrieved here (no "exception was never retrieved" traceback per pending write)."""

    def initialize(self, web: "WebDesigner") -> None:
        self.web = web
        self._sending = False
        self._dirty = False
        self._counted = False

    def prepare(self) -> None:
        _check_host(self)

    def open(self) -> None:
        if len(self.web._sockets) >= self.web.max_sockets:
            limit = self.web.max_sockets
            self.web.log.warning(f"designer web page: refused a page: {limit} pages are open (max_sockets={limit})")
            self.close(limits.WS_CLOSE_TRY_AGAIN, f"sockets: {limit} pages are open already (the limit is {limit})")
            return
        self.web._sockets.add(self)
        self._counted = True
        self.push()

    def push(self) -> None:
        """Send the current state now, or once the write in flight is done."""
        if self._sending:
            self._dirty = True
            return
        self._dirty = False
        try:
            future = self.write_message(self.web.state_json())
        except tornado.websocket.WebSocketClosedError:
            self._drop()
            return
        self._sending = True
        future.add_done_callback(self._sent)

    def _sent(self, future: "asyncio.Future[None]") -> None:
        self._sending = False
        if future.cancelled() or future.exception() is not None:  # retrieved: the socket closed
            self._drop()
        elif self._dirty:
            self.push()

    def _drop(self) -> None:
        self.web._sockets.discard(self)

    def on_message(self, message: str | bytes) -> None:
        return None  # clicks go through POST /answer

    def on_close(self) -> None:
        self._drop()


class WebDesigner:
    """HTTP + WebSocket server of the designer page, in its own thread (see the module doc).

    Args:
        host: address to bind (default loopback; another one is logged as a warning).
        port: TCP port; 0 = a free port chosen by the OS (``url`` tells it after ``start``).
        on_answer: ``(query_id, chosen) -> (ok, message)``, called from a worker thread of the
            server for each click that passed the server's checks; it may block.
        logger: anything with ``info``/``warning``/``error`` (an rclpy logger), default
            ``logging.getLogger(__name__)``.
        max_body, idle_timeout, body_timeout: the caps of ``ird_ros.web.limits`` (bytes, seconds).
        max_sockets: pages open at once (WebSockets, ``limits.MAX_SOCKETS``); one more is closed at
            once with code 1013 (try again later) and a reason naming the limit, which the page shows.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, on_answer: OnAnswer | None = None,
                 logger: Any = None, *, max_body: int = limits.MAX_BODY_BYTES,
                 idle_timeout: float = limits.IDLE_TIMEOUT, body_timeout: float = limits.BODY_TIMEOUT,
                 max_sockets: int = limits.MAX_SOCKETS) -> None:
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port: expected an integer in 0..65535, got {port!r}")
        if not isinstance(host, str) or not host:
            raise ValueError(f"host: expected a host name or address, got {host!r}")
        if on_answer is None:
            raise ValueError("on_answer: a callback (query_id, chosen) -> (ok, message) is required")
        for name, value in (("idle_timeout", idle_timeout), ("body_timeout", body_timeout), ("max_body", max_body)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name}: expected a number > 0, got {value!r}")
        if isinstance(max_sockets, bool) or not isinstance(max_sockets, int) or not max_sockets >= 1:
            raise ValueError(f"max_sockets: expected an integer >= 1, got {max_sockets!r}")
        self.max_sockets = max_sockets
        self.max_body = int(max_body)
        self.max_read = int(max_body) * (limits.MAX_BODY_READ_BYTES // limits.MAX_BODY_BYTES)
        self.idle_timeout = float(idle_timeout)
        self.body_timeout = float(body_timeout)
        self.host = host
        self.port = port
        self.on_answer = on_answer
        self.log = logger if logger is not None else logging.getLogger(__name__)
        self.loopback_only = is_loopback(host)
        if not self.loopback_only:
            self.log.warning(f"designer web page configured on {host}, not loopback: anyone who can "
                             "reach this address can answer the robot's queries (no authentication)")
        self._lock = threading.Lock()
        self._state = PageState()
        self._sockets: set[_SocketHandler] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server: tornado.httpserver.HTTPServer | None = None
        # One worker: clicks are sent one after another, as the inference node takes them.
        self._workers = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="web-answer")
        self._bound_port: int | None = None

    # ------------------------------------------------------------------ life cycle

    @property
    def url(self) -> str:
        """The page's address (the bound port once started)."""
        port = self._bound_port if self._bound_port is not None else self.port
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{port}/"

    def start(self) -> None:
        """Bind, then serve in a daemon thread; returns once the server accepts connections."""
        if self._thread is not None:
            raise RuntimeError("WebDesigner already started")
        sockets = tornado.netutil.bind_sockets(self.port, address=self.host)  # errors surface here
        self._bound_port = sockets[0].getsockname()[1]
        ready = threading.Event()
        self._thread = threading.Thread(target=self._serve, args=(sockets, ready), name="designer-web",
                                        daemon=True)
        self._thread.start()
        ready.wait()

    def _serve(self, sockets: list[Any], ready: threading.Event) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._loop = loop
        app = tornado.web.Application([
            (r"/", _PageHandler, {"web": self}),
            (r"/state", _StateHandler, {"web": self}),
            (r"/answer", _AnswerHandler, {"web": self}),
            (r"/ws", _SocketHandler, {"web": self}),
            (r"/static/(.*)", tornado.web.StaticFileHandler, {"path": str(WEB_DIR)}),
        ], websocket_ping_interval=limits.WS_PING_INTERVAL, websocket_ping_timeout=limits.WS_PING_TIMEOUT,
            websocket_max_message_size=limits.MAX_WS_MESSAGE_BYTES)
        self._server = tornado.httpserver.HTTPServer(
            app, idle_connection_timeout=self.idle_timeout, body_timeout=self.body_timeout,
            max_body_size=self.max_read, max_header_size=limits.MAX_HEADER_BYTES)
        self._server.add_sockets(sockets)
        loop.call_soon(ready.set)
        try:
            loop.run_forever()
        finally:
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    def stop(self, reason: str = "graph stopped") -> None:
        """Tell every open page that the graph ended (``reason``, unless :meth:`finish` gave one),
        close the server and its connections and join the thread (idempotent)."""
        thread, loop = self._thread, self._loop
        if thread is None or loop is None or not thread.is_alive():
            self._workers.shutdown(wait=False, cancel_futures=True)
            return
        with self._lock:
            if self._state.finished is None:
                self._state.finished = reason
            self._state.version += 1

        async def _shutdown() -> None:
            assert self._server is not None
            self._server.stop()
            message = self.state_json()
            for sock in list(self._sockets):  # the end state first, then the close
                try:
                    await asyncio.wait_for(sock.write_message(message), 2.0)
                except (tornado.websocket.WebSocketClosedError, TimeoutError, asyncio.CancelledError):
                    pass
                sock.close(1001, "graph stopped")
            await self._server.close_all_connections()
            loop.stop()

        loop.call_soon_threadsafe(lambda: loop.create_task(_shutdown()))
        thread.join(10.0)
        self._workers.shutdown(wait=False, cancel_futures=True)

    def __enter__(self) -> "WebDesigner":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ node -> page

    def show_world(self, world: dict[str, Any]) -> None:
        """The map to draw: ``height``, ``width``, ``class_names``, ``classes`` (H rows of W
        ints, row 0 = bottom, 255 = unknown), ``start`` ([row, col] or None), ``stamp``.
        A world with a new stamp makes the queries shown so far stale."""
        with self._lock:
            old = self._state.world
            if old is not None and old.get("stamp") != world.get("stamp"):
                self._state.stale.update(self._state.queries)
                self._state.queries.clear()
                self._state.accepted.clear()
                self._state.risk_map = None
                self._state.train_world = None
            self._state.world = copy.deepcopy(world)
        self._changed()

    def show_train_world(self, world: dict[str, Any]) -> None:
        """The training map, laid out as :meth:`show_world`'s (``start`` the training start);
        a proxies query's options are its proxies' plans on it."""
        with self._lock:
            self._state.train_world = copy.deepcopy(world)
        self._changed()

    def show_query(self, record: dict[str, Any]) -> None:
        """A new open query: ``query_id``, ``kind`` ("paths" or "proxies"; missing = "paths"),
        ``options`` (q lists of [row, col] cells; for "proxies" on the training map),
        ``option_proxies`` (q lists of p weights, "proxies"), ``proxy_feature_names`` (p names),
        ``feature_names``, ``option_features`` (q x d), ``information_gain``, ``strategy``, ..."""
        self._put_record(record)

    def show_answer(self, record: dict[str, Any]) -> None:
        """A query got answered (by anyone): the record with ``chosen`` >= 0 and ``answered_by``."""
        self._put_record(record)

    def _put_record(self, record: dict[str, Any]) -> None:
        query_id = int(record["query_id"])
        with self._lock:
            self._state.stale.discard(query_id)
            known = self._state.queries.get(query_id)
            if known is not None and known.get("chosen", -1) >= 0 and record.get("chosen", -1) < 0:
                return  # a re-shown proposal never reopens an answered query
            self._state.queries[query_id] = copy.deepcopy(record)
        self._changed()

    def show_posterior(self, posterior: dict[str, Any] | None, risk_map: dict[str, Any] | None) -> None:
        """The current belief: ``posterior`` (``feature_names``, ``mean``, ``std``,
        ``num_samples``, ``num_answers``, ``method``, ``converged``, ...) and ``risk_map``
        (``height``, ``width``, ``values`` H rows of W ints in 0..100, -1 unknown) or None."""
        with self._lock:
            if posterior is not None:
                self._state.posterior = copy.deepcopy(posterior)
            if risk_map is not None:
                self._state.risk_map = copy.deepcopy(risk_map)
        self._changed()

    def show_mission(self, mission: dict[str, Any]) -> None:
        """How the mission's last drive ended: ``text`` (one line the page shows), ``goal`` (the
        navigator's outcome: "succeeded", "aborted", "canceled" or None) and ``rob`` (Rob's final
        status: ``plan_label``, ``touched_lava``, ``reached_target``, ``true_return``, ``stopped``, ...
        or None); built by ``ird_ros.nodes.designer.mission_dict``."""
        with self._lock:
            self._state.mission = copy.deepcopy(mission)
        self._changed()

    def finish(self, reason: str) -> None:
        """The graph or mission ended (``reason``, e.g. "mission finished"): the page shows it,
        stops offering the open question and refuses further answers."""
        with self._lock:
            self._state.finished = str(reason)
        self._changed()

    # ------------------------------------------------------------------ state and clicks

    def state(self) -> dict[str, Any]:
        """A copy of what the page shows (the JSON of ``GET /state``)."""
        with self._lock:
            return copy.deepcopy(self._state.snapshot())

    def state_json(self) -> str:
        with self._lock:
            return json.dumps(self._state.snapshot(), allow_nan=False, default=float)

    def _changed(self) -> None:
        with self._lock:
            self._state.version += 1
        loop = self._loop
        if loop is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(self._broadcast)
            except RuntimeError:
                pass  # the loop closed meanwhile: no page to update

    def _broadcast(self) -> None:
        for sock in list(self._sockets):
            sock.push()

    async def answer(self, query_id: int, chosen: int) -> tuple[int, bool, str]:
        """Check a click, then send it through ``on_answer``; ``(http_status, ok, message)``."""
        with self._lock:
            refusal = self._state.refusal(query_id, chosen)
            if refusal is None:
                self._state.pending.add(query_id)
        if refusal is not None:
            status = 404 if refusal.startswith("query_id: unknown") else 400 if refusal.startswith("chosen") else 409
            self.log.info(f"designer web page refused an answer: {refusal}")
            return status, False, refusal
        self._changed()
        loop = asyncio.get_running_loop()
        try:
            ok, message = await loop.run_in_executor(self._workers, self.on_answer, query_id, chosen)
        except Exception as exc:  # a failing callback is a refused answer, the server keeps serving
            self.log.error(f"designer web page: on_answer({query_id}, {chosen}) raised {exc!r}")
            ok, message = False, f"error: {exc}"
        with self._lock:
            self._state.pending.discard(query_id)
            if ok:
                self._state.accepted[query_id] = chosen
        self._changed()
        if ok:  # the node's message (sampler statistics) goes to the log, the page gets its line
            self.log.info(f"designer web page: answer {query_id}/{chosen} accepted: {message}")
            return 200, True, thank_you(query_id, chosen)
        return 409, False, str(message)
