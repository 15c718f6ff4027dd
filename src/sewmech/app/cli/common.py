"""What every ``sewmech`` command shares: the typer app, the error guard, the options' checks,
and whether the command runs in a process of its own (the commands are in the other modules
of :mod:`sewmech.app.cli`).

Every command runs inside :func:`_guard`: an error sewmech raises on purpose is printed as one
line ``error: <where>: <what is wrong>. <what to do>`` with exit code 2 (docs/errors.md), Ctrl-C
and SIGTERM stop the command cleanly (exit 130 and 143; nothing half-written is left behind),
and anything unexpected is reported as an internal error (exit 70) without a traceback unless
``SEWMECH_DEBUG=1`` is set. Options are checked here, where they enter, before any work.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import io
import math
import os
import signal
import sys
import threading
from enum import Enum

import numpy as np
import typer
from rich.console import Console, ConsoleDimensions
from rich.markup import escape

from ...engine.errors import OptionError, OutputError, SewmechError
from ...engine.machine import Machine, load_machine

DEFAULT_MACHINE = "jb1-3"

def _click_exceptions():
    """click's exceptions as typer raises them (typer 0.29 carries its own copy of click)."""
    try:
        from typer._click import exceptions
    except ImportError:  # a typer that uses the click package
        from click import exceptions
    return exceptions


class _Group(typer.core.TyperGroup):
    """The command group, except that a mistake on the command line itself (an unknown option,
    a missing argument, a value of the wrong type: what click finds before a command runs) is
    one ``error:`` line like every other mistake (docs/errors.md), not a usage box."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        E = _click_exceptions()
        if sys.stdout is None:  # started with `>&-`: Python found no file descriptor 1
            _print_error("stdout: is closed (the command was started with >&-), so what it"
                         " prints has nowhere to go; nothing was done. Give it a place:"
                         " > FILE, or > /dev/null to discard it")
            sys.exit(EXIT_ERROR)
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except E.NoArgsIsHelpError as exc:  # the help is shown already
            sys.exit(exc.exit_code)
        except BrokenPipeError:  # the help or a usage line to a reader that went away
            _quiet_stdout()
            sys.exit(EXIT_PIPE)
        except SewmechError as exc:  # a mistake found while the command line is read
            _print_error(str(exc))
            sys.exit(EXIT_ERROR)
        except E.UsageError as exc:
            _print_error(_usage_error_text(exc))
            sys.exit(EXIT_ERROR)
        except E.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except typer.Abort:
            _print_error("interrupted; nothing half-written was left behind")
            sys.exit(EXIT_SIGINT)
        sys.exit(rv if isinstance(rv, int) else 0)

    def resolve_command(self, ctx, args):
        name, cmd, rest = super().resolve_command(ctx, args)
        if cmd is not None and not isinstance(cmd, typer.core.TyperGroup):
            _refuse_repeated_options(cmd, ctx, name, rest)
        return name, cmd, rest


def _refuse_repeated_options(cmd, parent, name: str, args: list[str]) -> None:
    """An option that takes one value (or a flag), given more than once, is refused
    (docs/errors.md): click would let the last one win silently (``--rpm 1000 --rpm 2000``
    ran at 2000 rpm, ``--gravity --no-gravity`` without gravity, ``--out a --out b`` wrote
    into b). Options that collect a list (``--set``, ``--phi-deg``, ...) are repeatable.
    The arguments are parsed here once more, without converting or checking anything: every
    other mistake is left to the command's own parse, which says it."""
    E = _click_exceptions()
    ctx = cmd.context_class(cmd, info_name=name, parent=parent, resilient_parsing=True)
    try:
        _, _, order = cmd.make_parser(ctx).parse_args(list(args))
    except E.UsageError:
        return
    counts: dict = {}
    for p in order:
        if getattr(p, "param_type_name", "") == "option" and not (
                p.multiple or p.count or p.is_eager):
            counts[p] = counts.get(p, 0) + 1
    for p, n in counts.items():
        if n < 2:
            continue
        names = [*p.opts, *p.secondary_opts]
        typed = []
        for k, token in enumerate(args):
            if token == "--":
                break
            if token in names:
                value = args[k + 1] if not p.is_flag and k + 1 < len(args) else None
                typed.append(token if value is None else f"{token} {value}")
            elif any(token.startswith(o + "=") for o in names if o.startswith("--")):
                typed.append(token)
        shown = f" ({', '.join(typed)})" if typed else ""
        what = "a switch counts once" if p.is_flag else "it takes one value"
        raise OptionError("/".join(names), f"is given {n} times{shown}: {what}, and only the"
                          " last would count", "Give it once")


def given(name: str) -> bool:
    """Whether the running command's parameter ``name`` (its Python name: ``step_deg``) was
    typed on the command line, not left at its default: an option that the command would
    ignore, or that contradicts another, is refused only when it was given."""
    try:
        from typer._click.globals import get_current_context
    except ImportError:  # a typer that uses the click package
        from click import get_current_context
    ctx = get_current_context(silent=True)
    if ctx is None or name not in ctx.params:
        return False
    source = ctx.get_parameter_source(name)
    return source is not None and source.name in ("COMMANDLINE", "ENVIRONMENT")


def refuse_unused(name: str, option: str, why: str, hint: str) -> None:
    """An :class:`OptionError` if the option ``option`` (parameter ``name``) was given although
    this run does not use it (``why``): never drop an option silently (docs/errors.md)."""
    if given(name):
        raise OptionError(option, why, hint)


def _usage_error_text(exc) -> str:
    """``<where>: <what is wrong>. <what to do>`` for a usage error of click: where is the
    option (else the command), and what to do is to read the command's help."""
    E = _click_exceptions()
    ctx = exc.ctx
    path = ctx.command_path if ctx is not None else "sewmech"
    where, what = path, exc.format_message()
    param = getattr(exc, "param", None)
    if isinstance(exc, E.BadParameter) and not isinstance(exc, E.MissingParameter) \
            and param is not None:
        opts = [o for o in getattr(param, "opts", []) if o.startswith("-")]
        where = "/".join(opts) if opts else f"{path} {str(param.name).upper()}"
        what = str(exc.message)
        # typer checks values with pydantic: its wording, without the library's prefixes
        what = what.replace("Value error, ", "").replace("Input should be ", "should be ")
    what = " ".join(what.split()).rstrip(".")
    what = what[0].lower() + what[1:] if what else "not understood"
    return f"{where}: {what}. Run '{path} --help' for what it takes"


app = typer.Typer(cls=_Group, name="sewmech", add_completion=False, no_args_is_help=True,
                  pretty_exceptions_enable=False,
                  help="sewmech: kinematics and dynamics of sewing-machine mechanisms (mm, s,"
                       " rad inside; degrees at the edges).")


#: the width of the lines written to a pipe or a file: no table there is ever narrower than
#: its values (a terminal's tables fit the terminal, wrapping a long cell onto more lines)
PIPE_WIDTH = 100_000


class _Console(Console):
    """rich's Console, except that output which is not a terminal (a pipe, a file) has no width
    limit: rich would lay tables out in 80 columns there (or in the width of a terminal the
    input comes from) and cut their values (``regulator…``). ``COLUMNS`` counts only in a
    terminal."""

    def _size(self) -> ConsoleDimensions:
        size = Console.size.fget(self)
        return size if self.is_terminal else ConsoleDimensions(PIPE_WIDTH, size.height)

    size = property(_size, Console.size.fset)

    def on_broken_pipe(self) -> None:
        """The reader went away (``| head``): :func:`_guard` stops the command quietly with
        exit code 141, as SIGPIPE would, whether it printed a table or JSON (rich itself would
        exit with 1)."""
        self.quiet = True
        raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    def _check_buffer(self) -> None:
        try:
            super()._check_buffer()
        except BrokenPipeError:
            raise
        except OSError as exc:  # /dev/full, a full disk, a file-size limit
            raise _stream_error("stderr" if self.stderr else "stdout", exc) from None


console = _Console()
err_console = _Console(stderr=True)

#: exit codes: 2 a user error (bad file, option or output path), 70 an internal error,
#: 130 interrupted by Ctrl-C; 143 / 129 by SIGTERM / SIGHUP (128 + the signal's number)
EXIT_ERROR, EXIT_INTERNAL, EXIT_SIGINT = 2, 70, 130
#: the reader of stdout went away (`| head`): 128 + SIGPIPE, as a program the signal ends
EXIT_PIPE = 141
#: the finest shaft-angle step of any command, deg (36,000 positions per turn)
MIN_STEP_DEG = 0.01


class Format(str, Enum):
    csv = "csv"
    json = "json"


class Terminated(BaseException):
    """Raised in the main thread when SIGTERM or SIGHUP arrives, so that every ``finally`` and
    context manager on the way out runs (staging directories and temporary files are
    removed)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def print_json(data) -> None:
    """A command's result as one line of strict JSON on stdout (``--json``): no NaN or
    infinity (:func:`sewmech.app.files.io.dump_json`). Written and flushed here, inside the
    command's :func:`_guard`: a full disk or a reader that went away is the command's error,
    not one of the interpreter's shutdown."""
    from ..files.io import dump_json

    buf = io.StringIO()
    dump_json(data, buf)
    buf.write("\n")
    try:
        sys.stdout.write(buf.getvalue())
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise _stream_error("stdout", exc) from None


def _stream_error(name: str, exc: OSError) -> OutputError:
    """Writing to stdout (or stderr) failed: located, and what to do. What is still buffered
    for stdout is dropped (the interpreter's last flush would fail on it again)."""
    if name == "stdout":
        _quiet_stdout()
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        return OutputError(name, "the output could not be written: the disk is full (or a"
                           " quota or file-size limit is reached)", "Free some space, or send"
                           " the output elsewhere")
    return OutputError(name, f"the output could not be written ({exc.strerror or exc})",
                       "Send it elsewhere (> FILE)")


def _quiet_stdout() -> None:
    """stdout to /dev/null: what is still buffered for a reader that went away is dropped
    (the interpreter's last flush would fail on it)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _print_error(text: str) -> None:
    err_console.print(f"[bold red]error:[/] {escape(text)}", markup=True, highlight=False,
                      soft_wrap=True)


@contextlib.contextmanager
def _guard():
    """One place where every command's failures become one clear line and an exit code."""
    from ..files import outdir

    old: dict = {}
    outdir.request_stop(None)
    if threading.current_thread() is threading.main_thread():
        # each handler notes its exception before raising it: one raised while a weakref
        # callback or a __del__ runs is swallowed by Python, and the note still keeps the
        # command's files from moving in (outdir.output_dir checks it before its commit)
        def on_term(signum, frame):
            exc = Terminated(signum)
            outdir.request_stop(exc)
            raise exc

        def on_int(signum, frame):
            exc = KeyboardInterrupt()
            outdir.request_stop(exc)
            raise exc

        for sig in (signal.SIGTERM, signal.SIGHUP):
            old[sig] = signal.signal(sig, on_term)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # (not if ignored)
            old[signal.SIGINT] = signal.signal(signal.SIGINT, on_int)
    try:
        try:
            yield
        except (typer.Exit, typer.Abort, KeyboardInterrupt, Terminated):
            raise
        except BaseException as exc:
            # a signal that arrived while code below was unwinding (a `finally` of matplotlib's
            # that failed on the half-drawn figure: "Invalid bounding box") is still the reason
            # the command stops, not the error raised on the way out
            cause = _interruption(exc)
            if cause is not None:
                raise cause from None
            raise
    except (typer.Exit, typer.Abort):
        raise
    except SewmechError as exc:
        _print_error(str(exc))
        raise typer.Exit(EXIT_ERROR) from None
    except KeyboardInterrupt:
        _print_error("interrupted (Ctrl-C); nothing half-written was left behind")
        raise typer.Exit(EXIT_SIGINT) from None
    except Terminated as exc:
        name = signal.Signals(exc.signum).name
        _print_error(f"terminated ({name}); nothing half-written was left behind")
        raise typer.Exit(128 + exc.signum) from None
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as SIGPIPE would
        _quiet_stdout()
        raise typer.Exit(EXIT_PIPE) from None
    except MemoryError:
        _print_error(_out_of_memory_text())
        raise typer.Exit(EXIT_ERROR) from None
    except (ValueError, KeyError) as exc:  # the library's argument checks ...
        if not _raised_by_sewmech(exc):  # ... but not numpy's "Singular matrix" (a bug)
            return _internal_error(exc)
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        _print_error(str(text))
        raise typer.Exit(EXIT_ERROR) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        _print_error(f"{where}{exc.strerror or exc}")
        raise typer.Exit(EXIT_ERROR) from None
    except Exception as exc:
        _internal_error(exc)
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        outdir.request_stop(None)  # (a stop the command handled itself, as serve does Ctrl-C)


def _internal_error(exc: BaseException):
    """Anything sewmech did not expect: exit 70, one line (SEWMECH_DEBUG=1: the traceback)."""
    if os.environ.get("SEWMECH_DEBUG"):
        raise exc
    _print_error(f"internal error ({type(exc).__name__}: {exc}). This is a bug in sewmech:"
                 " please report it with the command line; SEWMECH_DEBUG=1 shows the"
                 " traceback")
    raise typer.Exit(EXIT_INTERNAL) from None


_PACKAGE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _raised_by_sewmech(exc: BaseException) -> bool:
    """Whether sewmech's own code raised ``exc`` (a check of an argument, a name, a file),
    not a library it calls: a ValueError of numpy, scipy or pyarrow that reaches the command
    (numpy's "Singular matrix" from trial-balance's fit) is a bug of sewmech's, which should
    have refused the input first, not a user error without a place."""
    tb = exc.__traceback__
    if tb is None:
        return True
    while tb.tb_next is not None:
        tb = tb.tb_next
    return os.path.abspath(tb.tb_frame.f_code.co_filename).startswith(_PACKAGE + os.sep)


#: what to do when a command runs out of memory: the options it has that size its work
_MEMORY_HINTS = {
    "sweep": "Give a smaller --chunk (designs per batch call and per worker), or fewer"
             " --workers",
    "tolerance": "Give fewer --samples",
}


def _out_of_memory_text() -> str:
    """The out-of-memory line, with what to change for the command that ran out."""
    try:
        from typer._click.globals import get_current_context
    except ImportError:  # a typer that uses the click package
        from click import get_current_context
    ctx = get_current_context(silent=True)
    name = ctx.info_name if ctx is not None else None
    hint = _MEMORY_HINTS.get(name, "Use a coarser --step-deg, or fewer designs at a time")
    return f"{'sewmech ' + name if name else 'sewmech'}: out of memory; nothing half-written" \
        f" was left behind. {hint}"


def _interruption(exc: BaseException) -> BaseException | None:
    """The Ctrl-C or termination signal in the chain of exceptions that ``exc`` was raised
    while handling, if any."""
    seen = set()
    e = exc.__context__
    while e is not None and id(e) not in seen:
        if isinstance(e, (KeyboardInterrupt, Terminated)):
            return e
        seen.add(id(e))
        e = e.__context__
    return None


def command(name: str):
    """``@app.command(name)`` whose body runs inside :func:`_guard`."""
    def deco(fn):
        @functools.wraps(fn)
        def run(*args, **kwargs):
            with _guard():
                return fn(*args, **kwargs)

        return app.command(name)(run)
    return deco


# ---- options: checked where they enter -----------------------------------------------------


def _load(machine: str, sets: list[str] | None = None) -> Machine:
    """The machine (shipped name or file), with the ``--set`` changes applied."""
    m = load_machine(machine)
    values = _parse_sets(m, sets)
    return m.with_parameters(values, origin="--set") if values else m


#: the units --set reads: suffix -> (internal unit, factor to it); counterweights in g, kg and
#: g cm (static moment)
_UNITS = {"mm": ("mm", 1.0), "deg": ("rad", math.pi / 180.0), "rad": ("rad", 1.0),
          "kg": ("kg", 1.0), "g": ("kg", 1e-3), "gcm": ("kg mm", 1e-2)}


def _parse_sets(m: Machine, sets: list[str] | None) -> dict[str, float]:
    """--set NAME=VALUE[mm|deg|rad|g|kg|gcm] -> {name: value in internal units}."""
    values: dict[str, float] = {}
    designs = {f"{c}.{k}": ("mm" if k in ("width", "stroke") else "rad")
               for c in m.cam_designs for k in ("width", "stroke", "dwell", "orientation")}
    for item in sets or ():
        name, eq, text = (x.strip() for x in item.partition("="))
        if not eq or not name or not text:
            raise OptionError("--set", f"{item!r} is not NAME=VALUE",
                              "Write e.g. --set needle_bar.length=44 or"
                              " --set needle_crank.phase=5deg")
        unit = designs.get(name)
        if unit is None:
            try:
                unit = m.parameter_units[m.parameter_index(name)]
            except KeyError as exc:
                raise OptionError("--set", exc.args[0], f"`sewmech check {m.name} --parameters`"
                                  " lists them") from None
        suffix = next((u for u in sorted(_UNITS, key=len, reverse=True) if text.endswith(u)),
                      None)
        number = text[: -len(suffix)] if suffix else text
        try:
            value = float(number)
        except ValueError:
            raise OptionError("--set", f"{item!r}: {number!r} is not a number") from None
        if not math.isfinite(value):
            raise OptionError("--set", f"{item!r}: the value must be a finite number")
        if unit == "rad" and suffix is None:
            raise OptionError("--set", f"{item!r}: '{name}' is an angle; give its unit",
                              f"Write {name}={number}deg (or {number}rad)")
        if unit in ("kg", "kg mm") and suffix is None:
            example = f"{number}g" if unit == "kg" else f"{number}gcm"
            raise OptionError("--set", f"{item!r}: '{name}' is a counterweight's"
                              f" {'mass' if unit == 'kg' else 'static moment'}; give its unit",
                              f"Write {name}={example}")
        if suffix is not None and _UNITS[suffix][0] != unit:
            raise OptionError("--set", f"{item!r}: '{name}' is in {unit}, not {suffix}")
        if name in values:
            raise OptionError("--set", f"{item!r}: '{name}' is given twice", "Set it once")
        values[name] = value * (_UNITS[suffix][1] if suffix else 1.0)
    return values


def _phi_grid(step_deg: float, option: str = "--step-deg", min_step: float = MIN_STEP_DEG
              ) -> np.ndarray:
    """Shaft angles of one turn in steps of ``step_deg`` (which must divide 360), rad."""
    if not min_step <= step_deg <= 90.0:  # (a NaN fails too)
        raise OptionError(option, f"must be in {min_step:g} .. 90 deg, got {step_deg:g}",
                          f"Give e.g. {option} 5 (72 positions per turn)")
    n = int(round(360.0 / step_deg))
    if not math.isclose(n * step_deg, 360.0, rel_tol=1e-9):
        raise OptionError(option, f"{step_deg:g} deg does not divide 360",
                          "Give a step such as 0.5, 1, 2, 5 or 10")
    return np.radians(np.arange(n) * step_deg)


def _phi(step_deg: float, phi_deg: list[float] | None) -> np.ndarray:
    """--phi-deg angles if given (finite, any order), else one turn in --step-deg steps
    (both at once contradict each other: refused)."""
    if not phi_deg:
        return _phi_grid(step_deg)
    refuse_unused("step_deg", "--step-deg", f"and --phi-deg contradict each other (a turn in"
                  f" steps of {step_deg:g} deg, or only the angles"
                  f" {', '.join(f'{a:g}' for a in phi_deg)} deg)", "Give one of them")
    a = np.asarray(phi_deg, dtype=float)
    if not (np.abs(a) <= 1e6).all():
        raise OptionError("--phi-deg", f"must be finite angles in deg, got {list(phi_deg)}")
    return np.radians(a)


def _rpm(rpm: float | None) -> float | None:
    from ...engine.kinematics import check_speed

    return None if rpm is None else check_speed("--rpm", rpm)


def _settings(m: Machine, inputs: list[str] | None) -> dict[str, float]:
    """--input NAME=DEG options -> {name: rad}, checked against the declared ranges."""
    settings = {}
    for item in inputs or ():
        name, _, value = (x.strip() for x in item.partition("="))
        if name not in m.spec.inputs:
            raise OptionError("--input", f"{item!r}: machine '{m.name}' has no input"
                              f" '{name}'", f"Inputs: {', '.join(m.spec.inputs) or 'none'}")
        try:
            deg = float(value)
        except ValueError:
            raise OptionError("--input", f"{item!r}: expected NAME=DEGREES",
                              f"Write e.g. --input {name}=20") from None
        spec = m.spec.inputs[name]
        lo = spec.min_deg if spec.min_deg is not None else -1e6
        hi = spec.max_deg if spec.max_deg is not None else 1e6
        if not lo <= deg <= hi:  # (a NaN fails too)
            raise OptionError("--input", f"{item!r}: outside the range {lo:g} .. {hi:g} deg"
                              f" declared in [inputs.{name}] of {m.file}",
                              "Give a setting inside it")
        if name in settings:
            raise OptionError("--input", f"{item!r}: '{name}' is given twice",
                              "Give each input once")
        settings[name] = math.radians(deg)
    return settings


def _choice(option: str, value: str, choices, example: str | None = None) -> str:
    """``value`` if it is one of ``choices`` (strings, or an Enum whose values are the
    choices), else an :class:`OptionError`: one ``error:`` line through :func:`_guard`, where
    typer's own check of an Enum option prints a usage box instead. Declare such an option as
    a string with ``metavar=choices_metavar(choices)`` and check it here."""
    names = [getattr(c, "value", c) for c in choices]
    if value in names:
        return value
    import difflib

    close = difflib.get_close_matches(str(value), names, n=1, cutoff=0.6)
    hint = (f"Did you mean {option} {close[0]}?" if close
            else f"Give e.g. {option} {example or names[0]}")
    raise OptionError(option, f"{value!r} is not one of {', '.join(names)}", hint)


def choices_metavar(choices) -> str:
    """The metavar of a string option that takes one of ``choices``: ``[a|b|c]``."""
    return "[" + "|".join(getattr(c, "value", c) for c in choices) + "]"


def _bounded(option: str, value: float, lo: float, hi: float, unit: str, example: str):
    if not lo <= value <= hi:  # (a NaN fails too)
        raise OptionError(option, f"must be in {lo:g} .. {hi:g} {unit}, got {value:g}",
                          f"Give e.g. {option} {example}")
    return value


SET_HELP = ("change a parameter of the machine file, e.g. needle_bar.length=44 (mm),"
            " needle_crank.phase=5deg or a counterweight's cw.mass=25g, cw.static_moment=64gcm;"
            " names as `check --parameters` lists them; repeatable")


#: True in the ``sewmech`` process (set by :func:`run_as_process`): the process ends with the
#: command, so a report leaves its garbage to the process's end
#: (``write_report(collect_garbage=False)``) and keeps freed memory; a command run inside a
#: Python session (typer's test runner, a notebook) leaves both as they are
_PROCESS_ENDS = False


def process_ends() -> bool:
    """Whether the command runs in a ``sewmech`` process that ends with it."""
    return _PROCESS_ENDS


def run_as_process() -> None:
    """Run the command line as the ``sewmech`` process (the entry point's body)."""
    global _PROCESS_ENDS
    _PROCESS_ENDS = True
    import sewmech

    if signal.getsignal(signal.SIGINT) is sewmech._interrupted_while_starting:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # started: _guard's turn
    try:
        try:
            app()
        except KeyboardInterrupt:  # before a command's guard (while its modules load)
            _print_error("interrupted (Ctrl-C); nothing was written")
            sys.exit(EXIT_SIGINT)
    finally:
        # the process ends now: everything alive is frozen, so that the interpreter's
        # shutdown does not walk it again in its garbage collections (after a report, half a
        # second: every object numba, pandas and matplotlib made). Objects are still freed by
        # their reference counts; only cyclic garbage is left to the operating system (every
        # file sewmech writes is closed by its own `with`, and stdout and stderr are flushed
        # by the interpreter)
        import gc

        gc.freeze()
