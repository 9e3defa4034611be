"""The live page and its feed, served by Starlette on uvicorn (a thread beside the stream): ``/`` the page (the
floor plan with each person's dot, id and trail, the site's zones, lines and counts, the latest events, the 3D
skeletons, the frame rate and latency, each camera's floor as its people show it), ``/state`` the latest
snapshot as JSON, ``/stream`` every new snapshot as server-sent events. It binds to 127.0.0.1 unless told
otherwise; with a token, every request must carry it (``?token=`` or ``Authorization: Bearer``). Only the newest
snapshot is kept: a slow page skips snapshots, it never makes anything queue up."""

from __future__ import annotations

import asyncio
import json
import threading
from importlib import resources

from ray3d.errors import InputError

POLL_S = 0.01  # how often a page's feed looks for a newer snapshot


class LiveBoard:
    """The newest snapshot (a JSON text) and its number, shared between the stream and the server."""

    def __init__(self, site: dict | None = None):
        self.site = json.dumps(site or {"zones": [], "lines": []})
        self._lock = threading.Lock()
        self._text, self.version, self.closed = "{}", 0, False

    def publish(self, snapshot: dict) -> None:
        text = json.dumps(snapshot)
        with self._lock:
            self._text, self.version = text, self.version + 1

    def latest(self) -> tuple[int, str]:
        with self._lock:
            return self.version, self._text

    def close(self) -> None:
        self.closed = True


def live_app(board: LiveBoard, token: str | None = None):
    """The Starlette application of the live page."""
    from starlette.applications import Starlette
    from starlette.middleware import Middleware
    from starlette.middleware.base import BaseHTTPMiddleware
    from starlette.responses import HTMLResponse, JSONResponse, Response, StreamingResponse
    from starlette.routing import Route

    page = resources.files("ray3d").joinpath("assets", "live.html").read_text()

    async def index(request):
        return HTMLResponse(page)

    async def state(request):
        return Response(board.latest()[1], media_type="application/json")

    async def site(request):
        return Response(board.site, media_type="application/json")

    async def stream(request):
        async def snapshots():
            seen = -1
            while True:
                closed = board.closed  # read first: the snapshot sent after it is the last one
                version, text = board.latest()
                if version != seen:
                    seen = version
                    yield f"data: {text}\n\n"
                if closed:
                    break
                await asyncio.sleep(POLL_S)
            yield "event: end\ndata: {}\n\n"

        return StreamingResponse(snapshots(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    class TokenCheck(BaseHTTPMiddleware):
        async def dispatch(self, request, call_next):
            given = request.query_params.get("token") or \
                request.headers.get("authorization", "").removeprefix("Bearer ").strip()
            if given != token:
                return JSONResponse({"error": "a token is needed: ?token=... or Authorization: Bearer ..."},
                                    status_code=401)
            return await call_next(request)

    routes = [Route("/", index), Route("/state", state), Route("/site", site), Route("/stream", stream)]
    return Starlette(routes=routes, middleware=[Middleware(TokenCheck)] if token else [])


class LiveServer:
    """uvicorn serving ``live_app`` on a thread: ``start()`` returns once it listens (``url`` says where),
    ``stop()`` ends every feed and the server."""

    def __init__(self, board: LiveBoard, host: str = "127.0.0.1", port: int = 8765, token: str | None = None):
        if host not in ("127.0.0.1", "localhost", "::1") and not token:
            raise InputError(f"host {host}: serving beyond this machine needs a token", ("token",))
        try:
            import uvicorn
        except ImportError:
            raise InputError("the live page needs Starlette and uvicorn: pip install 'ray3d[live]'",
                             ("page",)) from None
        self.board, self.host, self.token = board, host, token
        self._server = uvicorn.Server(uvicorn.Config(live_app(board, token), host=host, port=port,
                                                     log_level="warning", access_log=False, lifespan="off"))
        self._thread = threading.Thread(target=self._server.run, name="live page", daemon=True)
        self.url = ""

    def start(self, wait_s: float = 10.0) -> str:
        self._thread.start()
        waited = 0.0
        while not self._server.started and self._thread.is_alive() and waited < wait_s:
            threading.Event().wait(0.02)
            waited += 0.02
        if not self._server.started:
            raise InputError(f"the live page could not listen on {self.host} (port taken?)", ("port",))
        port = self._server.servers[0].sockets[0].getsockname()[1]
        self.url = f"http://{self.host}:{port}/" + (f"?token={self.token}" if self.token else "")
        return self.url

    def stop(self) -> None:
        self.board.close()
        self._server.should_exit = True
        self._thread.join(timeout=5.0)
