"""The web application of ``sewmech serve``: one page and a JSON API (docs/serve.md).

Every answer of the API is JSON; every failure too: ``{"error": {"kind", "where", "what",
"hint"}}`` with a 4xx status for what the request got wrong (a bad machine file, a value out of
range, a design that does not assemble) and 500 for a bug, whose traceback goes to the server's
log and never to the client. The server keeps serving after any of them.

Safety: a machine is chosen by name from a table built at start (the shipped files, and the
file given on the command line); an uploaded file is bytes in the request's body, checked as
the command line checks files (size, encoding, TOML, the machine-file validation) and never
written anywhere. Each page gets its own session (a random token) with its own compiled
machine, so no page sees another's edits; the oldest sessions are dropped beyond
:data:`MAX_SESSIONS`.
"""

from __future__ import annotations

import json
import logging
import secrets
import threading
import time
from collections import OrderedDict
from pathlib import Path, PurePath
from urllib.parse import quote

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import ClientDisconnect, Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ...engine.errors import AssemblyError, SewmechError
from ...engine.spec import MAX_FILE_BYTES, toml_text
from .session import PageError, Session, error_dict, shipped_texts

log = logging.getLogger("sewmech.serve")

#: pages kept at once; the least recently used is dropped beyond (its page must load again)
MAX_SESSIONS = 32
#: the largest JSON request (a page's values), bytes
MAX_JSON_BYTES = 256 * 1024

#: the page's files, shipped as package data beside this module (found by this file's path:
#: importing ``sewmech.web`` by its short name rebinds the package's ``__spec__``, which
#: importlib.resources would read)
STATIC = Path(__file__).resolve().parent / "static"


class RequestError(Exception):
    def __init__(self, status: int, where: str, what: str, hint: str = ""):
        super().__init__(what)
        self.status, self.body = status, {"kind": "RequestError", "where": where, "what": what,
                                          "hint": hint}


def _error(status: int, body: dict) -> Response:
    """An error as JSON. ASCII with escapes: a message may quote what a request sent, and
    JSON text may carry a lone surrogate ("\\ud800") that UTF-8 cannot encode."""
    return Response(json.dumps({"error": body}, separators=(",", ":"), allow_nan=False),
                    status_code=status, media_type="application/json")


async def _body(request: Request, limit: int, what: str) -> bytes:
    """The request's body, at most ``limit`` bytes (413 beyond, without reading it all)."""
    size = request.headers.get("content-length")
    too_big = RequestError(413, what, f"is larger than {limit // 1024} kB", "Send a smaller"
                           f" {what}" if what != "machine file" else "A machine file is at"
                           f" most {MAX_FILE_BYTES // 2**20} MiB of TOML text")
    if size is not None and size.isdigit() and int(size) > limit:
        raise too_big
    chunks, n = [], 0
    async for chunk in request.stream():
        n += len(chunk)
        if n > limit:
            raise too_big
        chunks.append(chunk)
    return b"".join(chunks)


def _no_constant(name: str):
    """Python's JSON reader takes NaN, Infinity and -Infinity, which JSON has not."""
    raise RequestError(400, "request", f"is not valid JSON: {name} is not a JSON number",
                       "Send finite numbers")


async def _json(request: Request) -> dict:
    raw = await _body(request, MAX_JSON_BYTES, "request")
    if not raw.strip():
        return {}
    try:
        data = json.loads(raw, parse_constant=_no_constant)
    except (ValueError, RecursionError):
        raise RequestError(400, "request", "is not valid JSON", "Send an object such as"
                           " {\"set\": {\"needle_bar.length\": 45}}") from None
    if not isinstance(data, dict):
        raise RequestError(400, "request", "must be a JSON object", "Send {\"set\": {...}}")
    return data


class App:
    """The page's state: the machines it may open and the sessions of the pages."""

    def __init__(self, extra: dict[str, tuple[str, str]] | None = None,
                 initial: str | None = None, files: dict[str, Path] | None = None):
        self.machines = {**shipped_texts(), **(extra or {})}
        #: the machines read from a file on disk (the command line's): read again whenever a
        #: page opens one, so that an edit saved meanwhile is what the page shows and exports
        self.files = {k: Path(v) for k, v in (files or {}).items() if k in self.machines}
        self.initial = initial if initial in self.machines else (
            "jb1-3" if "jb1-3" in self.machines else next(iter(self.machines), None))
        self.sessions: OrderedDict[str, Session] = OrderedDict()
        self._lock = threading.Lock()

    def add(self, session: Session) -> str:
        token = secrets.token_urlsafe(16)
        with self._lock:
            self.sessions[token] = session
            while len(self.sessions) > MAX_SESSIONS:
                self.sessions.popitem(last=False)
        return token

    def get(self, token: str) -> Session:
        with self._lock:
            s = self.sessions.get(token)
            if s is None:
                raise RequestError(404, "session", "is unknown or expired (the server keeps"
                                   f" the last {MAX_SESSIONS} pages' machines)",
                                   "Load the machine again")
            self.sessions.move_to_end(token)
            return s

    # ---- endpoints -----------------------------------------------------------------------------
    async def index(self, request: Request):
        return FileResponse(str(STATIC / "index.html"), media_type="text/html")

    async def machines_list(self, request: Request):
        return JSONResponse({"initial": self.initial,
                             "machines": [{"name": k, "file": v[0]}
                                          for k, v in self.machines.items()]})

    async def open_machine(self, request: Request):
        data = await _json(request)
        name = data.get("machine")
        if not isinstance(name, str) or name not in self.machines:
            shown = repr(name) if len(repr(name)) <= 60 else repr(name)[:57] + "..."
            raise RequestError(404, "machine", f"{shown} is not a machine this server offers",
                               f"Choose one of {', '.join(self.machines)}, or upload a file")
        if name in self.files:
            await run_in_threadpool(self._reread, name)
        file, text = self.machines[name]
        return await self._open(text, file)

    def _reread(self, name: str) -> None:
        """The file's text as it is on disk now (a file deleted since: the text last read). A
        file that can no longer be read, or is no longer a machine file, is the page's error,
        located, as an upload's would be."""
        from ...engine.spec import read_toml_text

        path = self.files[name]
        if not path.exists():
            return
        text = read_toml_text(path)
        with self._lock:
            self.machines[name] = (self.machines[name][0], text)

    async def upload(self, request: Request):
        raw = await _body(request, MAX_FILE_BYTES, "machine file")
        # the file's name is only a label in messages: its last part, printable, short
        name = PurePath(request.query_params.get("name", "upload.toml").replace("\\", "/")).name
        name = "".join(c for c in name if c.isprintable())[:80] or "upload.toml"
        text = await run_in_threadpool(toml_text, raw, name)
        return await self._open(text, name)

    async def _open(self, text: str, file: str):
        session = await run_in_threadpool(Session.from_text, text, file)
        await run_in_threadpool(session.warm)
        token = self.add(session)
        return JSONResponse({"session": token, "machine": session.info()})

    async def turn(self, request: Request):
        return await self._timed(request, "turn")

    async def checks(self, request: Request):
        return await self._timed(request, "checks")

    async def _timed(self, request: Request, what: str):
        """A turn or the checks as JSON, with the server's time in a Server-Timing header
        (computing and encoding, ms; the page and the benchmark read it)."""
        s = self.get(request.path_params["token"])
        data = await _json(request)

        def work():
            t0 = time.perf_counter()
            answer = getattr(s, what)(data.get("set"))
            try:
                body = json.dumps(answer, separators=(",", ":"), allow_nan=False).encode()
            except ValueError as exc:  # a NaN or infinity the session let through: a bug
                raise RuntimeError(f"a non-finite number in the {what}: {exc}") from None
            return body, (time.perf_counter() - t0) * 1e3

        body, ms = await run_in_threadpool(work)
        return Response(body, media_type="application/json",
                        headers={"Server-Timing": f"{what};dur={ms:.1f}"})

    async def export_toml(self, request: Request):
        return await self._download(request, "export_toml", "-edited.toml", "application/toml")

    async def export_csv(self, request: Request):
        return await self._download(request, "curves_csv", "-curves.csv", "text/csv")

    async def export_dxf(self, request: Request):
        return await self._drawing(request, "dxf", "application/dxf")

    async def export_svg(self, request: Request):
        return await self._drawing(request, "svg", "image/svg+xml")

    async def _drawing(self, request: Request, fmt: str, media: str):
        """The session's design drawn at ``phi_deg`` (``{"set": {...}, "phi_deg": A}``) as a
        download named after the machine's file and the angle."""
        s = self.get(request.path_params["token"])
        data = await _json(request)
        phi = data.get("phi_deg", 0.0)
        text = await run_in_threadpool(s.drawing, data.get("set"), phi, fmt)
        name = f"{PurePath(s.file_name).stem}-phi{float(phi):g}.{fmt}"
        return Response(text, media_type=f"{media}; charset=utf-8",
                        headers={"Content-Disposition": content_disposition(name)})

    async def _download(self, request: Request, method: str, suffix: str, media: str):
        """A file of the session's current values (``Session.<method>``) as a download named
        after the machine's file."""
        s = self.get(request.path_params["token"])
        data = await _json(request)
        text = await run_in_threadpool(getattr(s, method), data.get("set"))
        name = PurePath(s.file_name).stem + suffix
        return Response(text, media_type=f"{media}; charset=utf-8",
                        headers={"Content-Disposition": content_disposition(name)})


def content_disposition(name: str) -> str:
    """The download header of a file named ``name`` (RFC 6266): the name itself as UTF-8,
    percent-encoded (``filename*``, RFC 8187), and an ASCII stand-in for clients that do not
    read it (``filename``: every other character, a quote, a backslash, a control character
    or a percent sign replaced by ``_``). A header is Latin-1 and one line: no name can break
    it."""
    ascii_name = "".join(c if " " <= c <= "~" and c not in '"\\%' else "_" for c in name)
    return (f'attachment; filename="{ascii_name}"; '
            f"filename*=UTF-8''{quote(name, safe='')}")


def create_app(extra: dict[str, tuple[str, str]] | None = None,
               initial: str | None = None, files: dict[str, Path] | None = None) -> Starlette:
    """The web application. ``extra``: more machines to offer, name -> (file name, text);
    ``initial``: the machine the page opens with; ``files``: which of ``extra`` are files on
    disk, name -> path, read again each time a page opens them."""
    state = App(extra, initial, files)

    def guarded(fn):
        async def endpoint(request: Request):
            try:
                return await fn(request)
            except RequestError as exc:
                return _error(exc.status, exc.body)
            except ClientDisconnect:  # the page closed or the client gave up: nobody to answer
                log.info("%s %s: the client went away before its request was read",
                         request.method, request.url.path)
                return Response(status_code=400)
            except AssemblyError as exc:
                body = error_dict(exc)
                body.update(unit=exc.unit, phi_deg=exc.phi_deg, ranges_deg=exc.ranges_deg)
                return _error(422, body)
            except PageError as exc:
                return _error(400, error_dict(exc))
            except (SewmechError, ValueError, KeyError) as exc:  # located errors of the library
                return _error(422, error_dict(exc))
            except MemoryError:
                return _error(507, {"kind": "MemoryError", "where": "server",
                                    "what": "out of memory", "hint": "Try a smaller file"})
            except Exception as exc:  # a bug: logged with its traceback, never sent
                log.exception("internal error in %s", request.url.path)
                return _error(500, {"kind": "InternalError", "where": "server",
                                    "what": f"internal error ({type(exc).__name__})",
                                    "hint": "This is a bug in sewmech: please report it with"
                                    " the machine file; the server's log has the details"})
        return endpoint

    routes = [
        Route("/", guarded(state.index)),
        Route("/api/machines", guarded(state.machines_list)),
        Route("/api/sessions", guarded(state.open_machine), methods=["POST"]),
        Route("/api/upload", guarded(state.upload), methods=["POST"]),
        Route("/api/sessions/{token}/turn", guarded(state.turn), methods=["POST"]),
        Route("/api/sessions/{token}/checks", guarded(state.checks), methods=["POST"]),
        Route("/api/sessions/{token}/export.toml", guarded(state.export_toml),
              methods=["POST"]),
        Route("/api/sessions/{token}/curves.csv", guarded(state.export_csv), methods=["POST"]),
        Route("/api/sessions/{token}/drawing.dxf", guarded(state.export_dxf), methods=["POST"]),
        Route("/api/sessions/{token}/drawing.svg", guarded(state.export_svg), methods=["POST"]),
        Mount("/static", StaticFiles(directory=str(STATIC)), name="static"),
    ]

    async def not_found(request, exc):
        path = request.url.path
        return _error(getattr(exc, "status_code", 404),
                      {"kind": "RequestError",
                       "where": path if len(path) <= 200 else path[:197] + "...",
                       "what": "no such page or API call", "hint": "See docs/serve.md"})

    app = Starlette(routes=routes, exception_handlers={404: not_found, 405: not_found})
    app.state.sewmech = state
    return app
