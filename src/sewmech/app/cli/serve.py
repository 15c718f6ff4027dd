"""``sewmech serve``: the interactive page (:mod:`sewmech.app.web`) on a local web server.
Registered on the shared app of :mod:`sewmech.app.cli.common` when :mod:`sewmech.app.cli`
imports this module."""

from __future__ import annotations

import contextlib
import errno
import socket

import typer

from ...engine.errors import OptionError
from ...engine.paths import user_path
from .common import DEFAULT_MACHINE, Terminated, command, console


_HOST_HINT = ("Give 127.0.0.1 (this computer only, the default) or an address of this"
              " computer; 0.0.0.0 serves your network")


def _address(host: str, port: int) -> tuple[int, tuple]:
    """The socket family and address ``--host`` names, or an OptionError against --host: an
    empty host (an unset variable, `--host "$HOST"`) would listen on every interface, as
    0.0.0.0 does, without anyone having asked for it; a name that does not resolve or an
    address that is no address was reported against --port."""
    if not host.strip():
        raise OptionError("--host", "is empty: the server would listen on every network"
                          " interface (as 0.0.0.0), open to anyone who reaches this computer",
                          _HOST_HINT + " on purpose")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                   flags=socket.AI_NUMERICSERV)
    except (socket.gaierror, UnicodeError) as exc:
        why = exc.strerror if isinstance(exc, socket.gaierror) and exc.strerror else str(exc)
        raise OptionError("--host", f"{host!r} is neither an address nor a name that resolves"
                          f" ({why})", _HOST_HINT) from None
    family, _, _, _, address = infos[0]
    return family, address


@command("serve")
def serve_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="the machine the page opens with: a"
                                  " shipped name or a machine file (TOML)"),
    port: int = typer.Option(8000, help="TCP port; 0 picks a free one (printed)"),
    host: str = typer.Option("127.0.0.1", help="address to listen on; the default serves this"
                             " computer only (0.0.0.0 serves your network: anyone who reaches"
                             " it can use the page)"),
):
    """Start the interactive page: change a dimension or the stitch regulator and watch the
    mechanism, its curves, forces and checks move (docs/serve.md). Ctrl-C stops it (exit
    code 0)."""
    from pathlib import Path

    import uvicorn

    from ...engine.machine import shipped_machines
    from ...engine.spec import parse_machine, read_toml_text
    from ..web.server import create_app

    if not 0 <= port <= 65535:
        raise OptionError("--port", f"must be 0 .. 65535, got {port}", "Give e.g. --port 8000,"
                          " or --port 0 for any free port")
    family, address = _address(host, port)
    extra, initial, files = {}, machine, {}
    if machine not in shipped_machines() or Path(machine).exists():
        path = user_path(machine, "MACHINE")
        text = read_toml_text(path)
        spec = parse_machine(text, str(path))  # a bad file stops here, with its location
        initial = f"{spec.machine.name} ({path.name})"
        extra[initial] = (path.name, text)
        files[initial] = path.resolve()  # read again whenever a page opens it
    app = create_app(extra, initial, files)
    try:
        sock = socket.socket(family)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)  # connections wait from now on, while the server starts
    except OSError as exc:
        if exc.errno == errno.EADDRNOTAVAIL:  # an address of another computer
            raise OptionError("--host", f"cannot listen on {host}: {exc.strerror or exc} (it is"
                              " not an address of this computer)", _HOST_HINT) from None
        raise OptionError("--port", f"cannot listen on {host}:{port}: {exc.strerror or exc}",
                          "Choose another --port (0: any free one)") from None
    bound = sock.getsockname()[1]
    shown = f"[{host}]" if ":" in host else host
    with contextlib.suppress(KeyboardInterrupt, Terminated):
        # Ctrl-C, the documented way to stop the page's server (or a service manager's
        # SIGTERM), is a normal end with exit code 0. Once it runs, uvicorn closes the
        # connections on the signal, then raises it again, which ends here
        console.print(f"sewmech: the page is at http://{shown}:{bound}/ (Ctrl-C stops the"
                      " server)", highlight=False, soft_wrap=True)
        config = uvicorn.Config(app, log_level="warning", lifespan="off")
        uvicorn.Server(config).run(sockets=[sock])
    console.print("sewmech: the page's server stopped", highlight=False)
