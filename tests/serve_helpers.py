"""A real ``sewmech serve`` server for the page's tests: uvicorn on 127.0.0.1 on a free port, in
a thread of the test process, always stopped when the test module is done."""

from __future__ import annotations

import contextlib
import json
import socket
import threading
import time
import urllib.error
import urllib.request


@contextlib.contextmanager
def running_server(extra=None, initial=None, files=None):
    import uvicorn

    from sewmech.app.web.server import create_app

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(extra, initial, files), log_level="warning",
                                           lifespan="off"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 20
        while not server.started:
            if time.monotonic() > deadline or not thread.is_alive():
                raise RuntimeError("the test server did not start")
            time.sleep(0.02)
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(10)
        sock.close()


def call(url: str, data=None, *, raw: bytes | None = None, method: str | None = None):
    """(status, parsed JSON or text) of one request; ``data`` is sent as JSON."""
    body = raw if raw is not None else (None if data is None else json.dumps(data).encode())
    req = urllib.request.Request(url, data=body, method=method or ("POST" if body is not None
                                                                   else "GET"))
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            status, text, ctype = r.status, r.read().decode(), r.headers.get("content-type", "")
    except urllib.error.HTTPError as exc:
        status, text, ctype = exc.code, exc.read().decode(), exc.headers.get("content-type", "")
    return status, (json.loads(text) if "json" in ctype else text)
