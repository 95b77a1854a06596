"""The browser host: a local web server for one :class:`~warp_spt.viewer.session.Session`.

``warp-spt view [-obj F]... [-mtl F]... [--up y] [--port N] [--no-browser]`` (:mod:`warp_spt.cli.view`)
serves the page on 127.0.0.1 (a free port unless ``--port``), prints its URL and opens the browser. The page
is ``static/index.html``, which runs the same ``static/viewer.js`` as the Jupyter widget over a
WebSocket. aiohttp serves both the page and the socket from one asyncio loop; the session's
render thread hands messages to that loop with ``call_soon_threadsafe``.

Only this machine may connect: the server binds 127.0.0.1 and refuses requests whose Host or
Origin header names another site (a web page elsewhere could otherwise reach it through DNS
rebinding). Ctrl-C stops it with one line and exit status 130; SIGTERM with 143.
"""

from __future__ import annotations

import asyncio
import collections
import importlib.resources
import json
import signal
import struct
import sys
import threading
import webbrowser
from typing import Sequence, TextIO

from . import messages

PROG = "warp-spt view"
EXIT_OK, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_TERMINATED = 0, 2, 130, 143
STATIC = {"/": ("index.html", "text/html"), "/viewer.js": ("viewer.js", "text/javascript")}
MAX_MESSAGE = 1 << 20        # the page sends small JSON messages only


def pack(message: dict, buffers: Sequence[bytes]) -> bytes:
    """One binary WebSocket frame: [uint32 LE header length][JSON header][buffers...]."""
    header = json.dumps({"message": message, "buffers": [len(b) for b in buffers]}).encode()
    return b"".join([struct.pack("<I", len(header)), header, *map(bytes, buffers)])


def static_text(name: str) -> bytes:
    """A file of the front end, from the installed package."""
    return importlib.resources.files("warp_spt.viewer").joinpath("static", name).read_bytes()


class _Client:
    """One page's socket. Messages go out in order, except frames: only the newest waits, so a
    slow page drops frames instead of falling behind."""

    def __init__(self, ws, loop: asyncio.AbstractEventLoop):
        self.ws, self.loop = ws, loop
        self.messages: collections.deque = collections.deque()
        self.frame = None
        self.wake = asyncio.Event()

    def push(self, message: dict, buffers: list) -> None:
        """Queue a message; safe from any thread."""
        try:
            self.loop.call_soon_threadsafe(self._enqueue, message, buffers)
        except RuntimeError:          # the loop has closed: the server is stopping
            pass

    def _enqueue(self, message: dict, buffers: list) -> None:
        if message.get("type") == "frame":
            self.frame = (message, buffers)
        else:
            self.messages.append((message, buffers))
        self.wake.set()

    async def pump(self) -> None:
        """Send what is queued until the page goes away."""
        try:
            await self._pump()
        except ConnectionError:       # the page closed while a message was on its way
            pass

    async def _pump(self) -> None:
        while True:
            await self.wake.wait()
            self.wake.clear()
            while self.messages:
                await self._send(*self.messages.popleft())
            if self.frame is not None:
                frame, self.frame = self.frame, None
                await self._send(*frame)

    async def _send(self, message: dict, buffers: list) -> None:
        if buffers:
            await self.ws.send_bytes(pack(message, buffers))
        else:
            await self.ws.send_str(json.dumps(message))


class ViewerServer:
    """Serves ``session`` at http://127.0.0.1:PORT/ (``port`` None or 0: a free one).

    :meth:`run` blocks on the main thread until Ctrl-C; :meth:`start_thread` runs the server on a
    background thread instead (tests, scripts) and :meth:`stop_thread` ends it.
    """

    def __init__(self, session, port: int | None = None, host: str = "127.0.0.1"):
        self.session, self.host, self.port = session, host, port or 0
        self.url: str | None = None
        self._runner = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stopped: asyncio.Event | None = None
        self._sockets: set = set()       # the pages' open websockets, closed first on shutdown

    def _app(self):
        from aiohttp import web

        @web.middleware
        async def local_only(request, handler):
            if not self._allowed(request):
                raise web.HTTPForbidden(text="the warp_spt viewer only answers pages it served itself")
            return await handler(request)

        app = web.Application(middlewares=[local_only], client_max_size=MAX_MESSAGE)
        app.router.add_get("/", self._static)
        app.router.add_get("/viewer.js", self._static)
        app.router.add_get("/ws", self._socket)
        app.router.add_get("/favicon.ico", self._no_icon)
        return app

    async def start(self) -> str:
        """Bind and start serving; returns the URL."""
        from aiohttp import web

        self._runner = web.AppRunner(self._app(), handle_signals=False, access_log=None)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        await site.start()
        self.port = self._runner.addresses[0][1]
        self.url = f"http://{self.host}:{self.port}/"
        return self.url

    async def close(self) -> None:
        """Close every page's socket first: the runner's clean-up waits for the open handlers, which
        a connected page keeps open (for tens of seconds)."""
        from aiohttp import WSCloseCode

        for ws in list(self._sockets):
            await ws.close(code=WSCloseCode.GOING_AWAY, message=b"the viewer is shutting down")
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    # -- handlers
    def _allowed(self, request) -> bool:
        hosts = {f"127.0.0.1:{self.port}", f"localhost:{self.port}"}
        origin = request.headers.get("Origin")
        return request.host in hosts and (origin is None or origin in {f"http://{h}" for h in hosts})

    async def _no_icon(self, request):
        from aiohttp import web

        return web.Response(status=204)          # no 404 in the page's console

    async def _static(self, request):
        from aiohttp import web

        name, kind = STATIC[request.path]
        return web.Response(body=static_text(name), content_type=kind, charset="utf-8",
                            headers={"Cache-Control": "no-store"})

    async def _socket(self, request):
        from aiohttp import WSMsgType, web

        ws = web.WebSocketResponse(max_msg_size=MAX_MESSAGE, heartbeat=30.0)
        await ws.prepare(request)
        client = _Client(ws, asyncio.get_running_loop())
        self.session.add_listener(client.push)
        pump = asyncio.create_task(client.pump())
        self._sockets.add(ws)
        try:
            async for raw in ws:
                if raw.type == WSMsgType.TEXT:
                    self._receive(raw.data, client)
        finally:
            self._sockets.discard(ws)
            self.session.remove_listener(client.push)
            pump.cancel()
        return ws

    def _receive(self, text: str, client: _Client) -> None:
        try:
            message = messages.parse(text)      # the session checks its fields (messages.checked)
        except ValueError as err:
            client.push({"type": "notice", "level": "error", "text": str(err)}, [])
            return
        self.session.handle(message, reply=client.push)

    # -- running
    async def _serve_until_stopped(self, on_ready) -> None:
        self._stopped = asyncio.Event()
        await self.start()
        on_ready(self.url)
        try:
            await self._stopped.wait()
        finally:
            await self.close()

    def run(self, open_browser: bool = True, out: TextIO | None = None) -> int:
        """Serve until Ctrl-C (130) or SIGTERM (143); prints the URL, opens the browser."""
        out = out or sys.stdout
        terminated = []

        def ready(url: str) -> None:
            print(f"{PROG}: serving {url} (Ctrl-C to stop)", file=out, flush=True)
            loop = asyncio.get_running_loop()
            if threading.current_thread() is threading.main_thread():
                loop.add_signal_handler(signal.SIGTERM, lambda: (terminated.append(1), self._stopped.set()))
            if open_browser:
                threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()

        try:
            asyncio.run(self._serve_until_stopped(ready))
        except KeyboardInterrupt:
            return EXIT_INTERRUPTED
        finally:
            self.session.close(timeout=5.0)
        return EXIT_TERMINATED if terminated else EXIT_OK

    def start_thread(self, timeout: float = 30.0) -> str:
        """Serve on a background thread; returns the URL once it is listening."""
        ready = threading.Event()

        def target() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            try:
                loop.run_until_complete(self._serve_until_stopped(lambda url: ready.set()))
            finally:
                loop.close()

        self._thread = threading.Thread(target=target, name="warp_spt-viewer-server", daemon=True)
        self._thread.start()
        if not ready.wait(timeout):
            raise TimeoutError("the viewer server did not start")
        return self.url

    def stop_thread(self, timeout: float = 10.0) -> None:
        """Stop a server started with :meth:`start_thread` (the session is left running)."""
        if self._loop is not None and self._stopped is not None:
            self._loop.call_soon_threadsafe(self._stopped.set)
        if self._thread is not None:
            self._thread.join(timeout)


def serve(scene=None, camera=None, *, objs: Sequence[str] = (), mtls: Sequence[str] = (), up: str | None = None,
          port: int | None = None, open_browser: bool = True, out: TextIO | None = None, **settings) -> int:
    """Serve a live view until Ctrl-C; returns the exit status (0, 130 on Ctrl-C, 143 on SIGTERM).

    ``scene`` is a :class:`warp_spt.Scene`, or None to load ``objs``/``mtls`` (the built-in demo
    when none are given; a :class:`warp_spt.SceneError` is then shown on the page, which can reload
    the files). ``settings`` are :class:`~warp_spt.viewer.session.ViewSettings` fields (width,
    height, integrator, sampler, max_depth, sky, ...).
    """
    from .session import open_session

    session = open_session(scene, camera, objs=objs, mtls=mtls, up=up, **settings)
    return ViewerServer(session, port).run(open_browser=open_browser, out=out)


