"""``pliant view``'s server: the page and its libraries over HTTP, one coupled session per
websocket connection (each browser tab its own), on loopback unless told otherwise.

Files served: the page (``static/``, part of the package) and three.js and the WebXR
emulator (copied into a wheel at build time; in a checkout, from ``web/node_modules``);
every other path is refused. The scene, its meshes and saved sessions are read from the scene's
folder
only (``state.inside``). A cross-site page cannot drive a session: the websocket's Origin
must be the server's own address.
"""

from __future__ import annotations

import asyncio
import logging
import mimetypes
import os
import threading
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from pliant.errors import InputError, PliantError
from pliant.viewer import protocol as P
from pliant.viewer.protocol import ProtocolError

STATIC = Path(__file__).with_name("static")
IDLE_TIMEOUT = 1800.0  # s a tab may send nothing before its session (a slot, a worker) is
# freed: an open tab left for the night held its slot forever; the page says to reload
SEND_TIMEOUT = 15.0  # s a message may wait for a client that does not read; then it goes
VENDOR = {"three": "three", "iwer": "iwer"}  # URL prefix under /vendor/ -> npm package
log = logging.getLogger("pliant.viewer")


def node_modules() -> Path:
    """Where the page's npm packages are: ``PLIANT_WEB_MODULES`` when set, else those a
    wheel carries (``viewer/vendor``, copied at build time by setup.py), else the
    repository's ``web/node_modules`` (a development install)."""
    env = os.environ.get("PLIANT_WEB_MODULES")
    bundled = Path(__file__).resolve().parent / "vendor"
    if env:
        path = Path(env)
    elif (bundled / "three" / "build" / "three.module.js").is_file():
        path = bundled
    else:
        path = Path(__file__).resolve().parents[3] / "web" / "node_modules"
    if not (path / "three" / "build" / "three.module.js").is_file():
        raise PliantError(f"three.js is not installed in {path}: run `npm ci --prefix web` "
                          "in the repository (the README's second command does), or "
                          "install pliant's wheel, which carries it")
    return path


class _Dropped(Exception):
    """A client that stopped reading was disconnected."""


class Server:
    """Serves ``scene`` (a file inside ``root``, its folder by default) on ``host:port``
    (port 0: any free one). ``live``: accurate solves in worker processes (else inline,
    deterministic); ``elements``: the 3D resolution (default: the scene's); ``envelope``:
    a variation study's envelope.glb (or its folder), shown with the scene; ``display``:
    the triangles drawn of the obstacles; ``sessions``: the most tabs served at once
    (default: the cores, at least 2; one more is told the server is busy); ``idle``: the
    seconds a tab may send nothing before its session is closed (IDLE_TIMEOUT)."""

    def __init__(self, scene: Path, *, host: str = "127.0.0.1", port: int = 8765,
                 root: Path | None = None, live: bool = True,
                 elements: int | None = None, envelope: Path | None = None,
                 display: int | None = None, sessions: int | None = None,
                 idle: float = IDLE_TIMEOUT) -> None:
        scene = Path(scene).resolve()
        if not scene.is_file():
            raise InputError("scene", f"{scene} is not a file; give a scene file (TOML)")
        self.root = (root or scene.parent).resolve()
        self.scene = scene.relative_to(self.root)
        self.host, self.port = host, port
        self.live, self.elements = live, elements
        self.display = display  # the scene's display budget [triangles]; None: the default
        # Each tab's session has its own worker process (it keeps its warm start): at most
        # this many at once, so that tabs cannot exhaust the machine's memory.
        if sessions is not None and sessions < 1:
            raise InputError("sessions", f"must be at least 1, got {sessions}")
        self.sessions = sessions or max(2, os.cpu_count() or 2)
        self.open_sessions = 0
        if not idle > 0:
            raise InputError("idle", f"must be a positive number of seconds, got {idle}")
        self.idle = idle
        self.idled = 0  # sessions closed for sending nothing for ``idle`` seconds
        self.dropped = 0  # clients dropped for not reading
        self.envelopes = []
        if envelope is not None:
            from pliant.viewer.state import load_envelope  # noqa: PLC0415

            self.envelopes = load_envelope(envelope)
        self.modules = node_modules()
        self.connections = 0
        self._server: Any = None  # a websockets Server once started
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    # -- HTTP ------------------------------------------------------------------------------
    def _file(self, path: str) -> Path | None:
        """The file a GET path names, or None (not ours, or outside its folder)."""
        path = unquote(urlsplit(path).path)
        if "\x00" in path or len(path) > 512:  # no file of ours is named so
            return None
        if path in ("/", "/index.html"):
            return STATIC / "index.html"
        parts = path.lstrip("/").split("/", 2)
        if len(parts) == 2 and parts[0] == "static":
            base, rest = STATIC, parts[1]
        elif len(parts) == 3 and parts[0] == "vendor" and parts[1] in VENDOR:
            base, rest = self.modules / VENDOR[parts[1]], parts[2]
        else:
            return None
        base = base.resolve()
        try:
            target = (base / rest).resolve()
            if not target.is_relative_to(base) or not target.is_file():
                return None
        except (OSError, ValueError):  # a name too long for the file system, say
            return None
        return target

    def _allowed(self, authority: str | None) -> bool:
        """A Host (or an Origin's host and port) this server answers to: its port, and
        localhost, an IP address or the address it was told to listen on. A DNS name
        that merely resolves here is refused, so a rebinding page (evil.example:PORT
        pointed at 127.0.0.1) cannot read the scene or drive the grips."""
        import ipaddress  # noqa: PLC0415

        if not authority:
            return False
        parsed = urlsplit(f"//{authority}")
        try:
            port = parsed.port
        except ValueError:
            return False
        if port != self.port or parsed.hostname is None:
            return False
        host = parsed.hostname
        if host in ("localhost", self.host.strip("[]").lower()):
            return True
        try:
            ipaddress.ip_address(host)
        except ValueError:
            return False
        return True

    def _process_request(self, connection, request):
        from websockets.datastructures import Headers  # noqa: PLC0415
        from websockets.http11 import Response  # noqa: PLC0415

        hosts = request.headers.get_all("Host")
        host = hosts[0] if len(hosts) == 1 else None
        if not self._allowed(host):
            return connection.respond(403, "this server answers to its own address only "
                                      "(open it as http://127.0.0.1:PORT/)\n")
        if urlsplit(request.path).path == "/ws":
            origins = request.headers.get_all("Origin")
            if len(origins) > 1:
                return connection.respond(403, "one Origin, please\n")
            origin = origins[0] if origins else None
            if origin is not None and (urlsplit(origin).netloc != host
                                       or not self._allowed(urlsplit(origin).netloc)):
                return connection.respond(403, "cross-origin websocket refused\n")
            return None
        target = self._file(request.path)
        if target is None:
            return connection.respond(404, "not found\n")
        body = target.read_bytes()
        kind = mimetypes.guess_type(target.name)[0] or "application/octet-stream"
        if target.suffix == ".js":
            kind = "text/javascript"
        headers = Headers([("Content-Type", kind), ("Content-Length", str(len(body))),
                           ("Cache-Control", "no-cache"),
                           ("X-Content-Type-Options", "nosniff")])
        return Response(200, "OK", headers, body)

    # -- websocket -------------------------------------------------------------------------
    async def _handle(self, ws) -> None:


        self.connections += 1
        try:
            if self.open_sessions >= self.sessions:
                await self._close(ws, f"busy: {self.open_sessions} sessions are open, the "
                                  "most this server runs at once; close another tab, or "
                                  "start pliant view with a larger --sessions", 1013, "busy")
                return
            self.open_sessions += 1
            try:
                await self._session(ws)
            finally:
                self.open_sessions -= 1
        except _Dropped:
            pass

    async def _session(self, ws) -> None:
        from websockets.exceptions import ConnectionClosed  # noqa: PLC0415

        from pliant.viewer.state import ViewerState  # noqa: PLC0415

        try:
            state = await asyncio.to_thread(ViewerState, self.scene, self.root,
                                            live=self.live, elements=self.elements,
                                            envelopes=self.envelopes, display=self.display)
        except PliantError as err:
            await self._close(ws, f"the scene cannot be opened: {err}")
            return
        lock = asyncio.Lock()
        arrived = asyncio.Event()
        loop = asyncio.get_running_loop()

        def wake() -> None:  # from the worker's reader thread
            loop.call_soon_threadsafe(arrived.set)

        state.watch(wake)

        async def pump() -> None:  # accurate results, pushed as they arrive
            try:
                while True:
                    await arrived.wait()
                    arrived.clear()
                    # Sent under the lock, as the replies are: a frame made before a
                    # move's must not reach the page after it (it would show the old pose).
                    async with lock:
                        for message in state.take_accurate():
                            await self._send(ws, P.dump(message))
            except (ConnectionClosed, _Dropped):
                pass  # the reading loop sees it too, and closes the session

        task = asyncio.create_task(pump())
        try:
            while True:
                try:
                    raw = await asyncio.wait_for(ws.recv(), self.idle)
                except TimeoutError:
                    self.idled += 1
                    async with lock:
                        await self._close(ws, f"closed: this tab sent nothing for "
                                          f"{self.idle:g} s, and its session was freed for "
                                          "others; reload the page to start again", 1001,
                                          "idle")
                    break
                async with lock:
                    for reply in await self._reply(state, raw):
                        await self._send(ws, reply)
        except (ConnectionClosed, _Dropped):
            pass
        finally:
            task.cancel()
            await asyncio.to_thread(state.close)

    async def _close(self, ws, message: str, code: int = 1000, reason: str = "") -> None:
        """Tell the page why (an ``error`` message), then close the connection."""
        await self._send(ws, P.dump(P.ServerError(message=message)))
        await ws.close(code, reason)

    async def _send(self, ws, text: str) -> None:
        """Send, or drop a client that has not read for ``SEND_TIMEOUT`` (its session and
        worker are freed: it cannot hold them by never reading)."""
        try:
            await asyncio.wait_for(ws.send(text), SEND_TIMEOUT)
        except TimeoutError:
            self.dropped += 1
            log.warning("dropped a client that did not read for %g s", SEND_TIMEOUT)
            ws.transport.abort()
            raise _Dropped from None

    async def _reply(self, state, raw) -> list[str]:
        try:
            message = P.parse(raw)
            if isinstance(message, P.ClientMove):  # at display rate: a millisecond or two
                replies = state.handle(message)
            else:
                replies = await asyncio.to_thread(state.handle, message)
            return [P.dump(r) for r in replies]
        except ProtocolError as err:
            return [P.dump(P.ServerError(message=str(err), field=err.field))]
        except PliantError as err:
            return [P.dump(P.ServerError(message=str(err),
                                         field=getattr(err, "field", None)))]
        except Exception as err:
            log.exception("internal error on a message")
            return [P.dump(P.ServerError(message=f"internal error: {err!r}"))]

    # -- running ---------------------------------------------------------------------------
    async def _start(self) -> None:
        from websockets.asyncio.server import serve  # noqa: PLC0415

        self._server = await serve(self._handle, self.host, self.port,
                                   process_request=self._process_request,
                                   max_size=P.MAX_FRAME, max_queue=64)
        self.port = self._server.sockets[0].getsockname()[1]

    @property
    def addresses(self) -> list[str]:
        """The addresses its sockets are bound to (empty before it starts)."""
        if self._server is None:
            return []
        return [sock.getsockname()[0] for sock in self._server.sockets]

    def run(self, on_ready=None) -> None:
        """Serve until interrupted (Ctrl+C); ``on_ready(url)`` once listening."""
        async def main() -> None:
            await self._start()
            if on_ready is not None:
                on_ready(self.url)
            await self._server.serve_forever()

        try:
            asyncio.run(main())
        except OSError as err:
            raise PliantError(f"cannot listen on {self.host}:{self.port}: {err.strerror}; "
                              "choose another --port") from None

    def start(self) -> Server:
        """Serve from a background thread (tests, notebooks); returns once listening."""
        ready = threading.Event()
        failure: list[BaseException] = []

        def main() -> None:
            self._loop = asyncio.new_event_loop()
            try:
                self._loop.run_until_complete(self._start())
            except BaseException as err:
                failure.append(err)
                ready.set()
                return
            ready.set()
            self._loop.run_forever()
            self._loop.run_until_complete(self._loop.shutdown_asyncgens())
            self._loop.run_until_complete(self._loop.shutdown_default_executor())
            self._loop.close()

        self._thread = threading.Thread(target=main, daemon=True, name="pliant-view")
        self._thread.start()
        ready.wait()
        if failure:
            raise failure[0]
        return self

    def stop(self) -> None:
        """Close every connection (and its sessions' workers) and stop serving."""
        if self._loop is None or self._server is None:
            return

        async def shut() -> None:
            self._server.close()
            await self._server.wait_closed()

        asyncio.run_coroutine_threadsafe(shut(), self._loop).result(timeout=30)
        self._loop.call_soon_threadsafe(self._loop.stop)
        if self._thread is not None:
            self._thread.join(timeout=10)

    def __enter__(self) -> Server:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
