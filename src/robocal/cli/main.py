"""Entry point of the ``robocal`` command.

Exit codes: 0 success, 1 finished with warnings, 2 bad input or usage (one ``error:`` line, nothing
written), 3 device or communication failure, 70 internal error (a bug in robocal; the ``error:`` line names the
log file holding the traceback), 130 interrupted, 141 standard output closed early (``| head``).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import gc
import logging
import os
import platform
import shlex
import signal
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import typer
from typer.core import TyperArgument, TyperOption

from .. import __version__
from ..errors import CalibError, UsageError
from ..workflows.written import files_written
from . import _common, entry

app = typer.Typer(
    name="robocal",
    help="Calibrate robots: Robstride joints, LeRobot arms, Universal Robots kinematics.",
    no_args_is_help=True,
    epilog=(
        "Exit codes: 0 success; 1 finished with warnings; 2 bad input or usage (nothing written); "
        "3 device or communication failure; 70 internal error, a bug in robocal (the traceback is saved to the "
        "log file the error line names); 130 interrupted; 141 output closed early (| head)."
    ),
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _version_callback(value: bool) -> None:
    if value:
        _common.console.print(f"robocal {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """Calibrate robots: Robstride joints, LeRobot arms, Universal Robots kinematics."""


class UserInterruptError(CalibError):
    """Ctrl-C (or SIGTERM, SIGHUP) reached the CLI without the command handling it."""

    exit_code = 130


_written_before_main = 0


def written_this_command() -> tuple[Path, ...]:
    """The files the running command has written so far (atomically: each is whole)."""
    return files_written()[_written_before_main:]


def _interrupt_error(exc: KeyboardInterrupt) -> UserInterruptError:
    """The one line an interruption ends with, and its exit code (130, or 143 / 129 for SIGTERM / SIGHUP).

    When files were written before it (atomically, so each is whole), the line says which instead of calling
    the interruption an error.
    """
    signum = getattr(exc, "signum", None) or entry.first_signal() or int(signal.SIGINT)
    text = entry.interrupted_text(signum)
    written = files_written()[_written_before_main:]
    if written:
        text = f"{text} after writing {' and '.join(str(p) for p in written)} (complete)"
    err = UserInterruptError(text)
    err.exit_code = entry.exit_code_for(signum)
    return err


def _interruptible(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn a stray KeyboardInterrupt into an ``error: interrupted`` line (typer would exit 130 silently)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except KeyboardInterrupt as exc:
            entry.quiet_after_interrupt()
            raise _interrupt_error(exc) from None

    return wrapper


def _wrap_commands(typer_app: typer.Typer) -> None:
    for info in typer_app.registered_commands:
        if info.callback is not None:
            info.callback = _interruptible(info.callback)
    for group in typer_app.registered_groups:
        if group.typer_instance is not None:
            _wrap_commands(group.typer_instance)


def _register() -> None:
    from . import dataset, demo, files, health, kinematics, lerobot, sim, sweep, ur, view

    files.register(app)
    sweep.register(app)
    demo.register(app)
    view.register(app)
    app.add_typer(lerobot.app, name="lerobot")
    app.add_typer(ur.app, name="ur")
    app.add_typer(dataset.app, name="dataset")
    app.add_typer(kinematics.app, name="kinematics")
    app.add_typer(sim.app, name="sim")
    app.add_typer(health.app, name="health")
    _wrap_commands(app)


_register()


class _NoteHandler(logging.Handler):
    """Print library notes (e.g. a write through a symbolic link) as ``note:`` lines on standard error."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"note: {record.getMessage()}\n")
        sys.stderr.flush()


class _PageWarningHandler(logging.Handler):
    """Print what a served page reports (refused requests, unreadable clients, exposure) as ``warning:`` lines."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"warning: {record.getMessage()}\n")
        sys.stderr.flush()


def _install_note_handler() -> None:
    for name in ("robocal.fileio", "robocal.notes"):  # robocal.notes: what a previous run left (workflows)
        logger = logging.getLogger(name)
        if not any(isinstance(h, _NoteHandler) for h in logger.handlers):
            logger.addHandler(_NoteHandler(logging.INFO))
        logger.setLevel(logging.INFO)
        logger.propagate = False
    pages = logging.getLogger("robocal.viewer")
    if not any(isinstance(h, _PageWarningHandler) for h in pages.handlers):
        pages.addHandler(_PageWarningHandler(logging.WARNING))
    pages.propagate = False


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit code (also used as the console-script entry point).

    Args:
        argv: Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns:
        The process exit code.
    """
    global _written_before_main
    _written_before_main = len(files_written())  # a test calling main() twice: only this command's files
    _install_note_handler()
    command = _command()
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        _version_needs_no_value(args)
        rv = command.main(args=args, prog_name="robocal", standalone_mode=False)
        sys.stdout.flush()  # a closed pipe shows here, inside the handlers below, not at interpreter exit
    except CalibError as exc:
        if exc.exit_code == 130:
            entry.quiet_after_interrupt()
        if isinstance(exc, UserInterruptError):
            _print_interrupted(str(exc))
            return exc.exit_code
        _common.print_error(str(exc))
        return _signal_exit_code(exc.exit_code)
    except KeyboardInterrupt as exc:
        entry.quiet_after_interrupt()
        err = _interrupt_error(exc)
        _print_interrupted(str(err))
        return err.exit_code
    except Exception as exc:  # click usage errors carry format_message/exit_code; anything else is a bug
        fmt = getattr(exc, "format_message", None)
        if type(exc).__name__ == "NoArgsIsHelpError":  # help was shown for a bare group
            return 0
        if callable(fmt):
            _common.print_error(str(fmt()))
            code = getattr(exc, "exit_code", 2)
            return code if isinstance(code, int) and code != 1 else 2
        if type(exc).__name__ == "Abort":
            _common.print_error("aborted")
            return 130
        if isinstance(exc, BrokenPipeError):  # e.g. `robocal check ... | head -1`: not an error of robocal
            return _closed_pipe()
        if isinstance(exc, MemoryError):  # an input too large for the memory this process may use: not a bug
            exc.__traceback__ = None  # let go of what the failed command held before printing
            gc.collect()
            _common.print_error(_out_of_memory(args))
            return _common.EXIT_BAD_INPUT
        if isinstance(exc, OSError) and exc.errno == errno.ENAMETOOLONG:  # a path the user gave: not a bug
            name = os.fsdecode(exc.filename) if exc.filename is not None else "a path"
            shown = name if len(name) <= 80 else f"{name[:40]}…{name[-30:]} ({len(os.fsencode(name))} bytes)"
            _common.print_error(
                f"{shown}: file name too long (a name may have at most 255 bytes, a path at most 4095)"
            )
            return _common.EXIT_BAD_INPUT
        return _report_bug(exc, args)
    if isinstance(rv, int):
        return _signal_exit_code(rv)
    return 0


def _command_words(args: Sequence[str]) -> str:
    """The command path of ``args`` (``convert``, ``dataset recalibrate``): the leading words naming commands."""
    group: Any = typer.main.get_command(app)
    words: list[str] = []
    for arg in args:
        sub = getattr(group, "commands", {}).get(arg)
        if sub is None:
            break
        words.append(arg)
        group = sub
    return " ".join(words)


def _out_of_memory(args: Sequence[str]) -> str:
    """The one line for a command that ran out of memory: which command, and the process's memory limit if set."""
    command = f"robocal {_command_words(args)}".strip()
    limit = ""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            limit = f" ({soft // (1024 * 1024)} MiB of address space, ulimit -v)"
    except (ImportError, OSError, ValueError):  # no resource module (Windows)
        pass
    return (
        f"{command} ran out of memory{limit}: an input is too large for this machine (robocal's input "
        "limits: docs/design.md, Input limits)"
    )


def _signal_exit_code(code: int) -> int:
    """130 (interrupted) becomes 143 / 129 when the interruption was SIGTERM / SIGHUP (``entry.first_signal``)."""
    first = entry.first_signal()
    if code == 130 and first is not None:
        return entry.exit_code_for(first)
    return code


def _print_interrupted(text: str) -> None:
    """``error: interrupted``; a line saying what was written when files were (an interruption, not an error)."""
    if " after writing " in text:
        sys.stderr.write(f"{text}\n")
        sys.stderr.flush()
    else:
        _common.print_error(text)


class _FlagOption(TyperOption):
    """A boolean flag: its help row shows no ``<bool>`` value, since the flag takes none."""

    def display_type_rich(self, ctx: Any) -> str | None:
        return None


class _PositionalArgument(TyperArgument):
    """A positional argument shown as ``SRC`` (usage line and help table), not ``{src}``."""

    def _usage_display_name(self) -> str:
        name = (self.metavar or (self.name or "").upper()) + ("..." if self.nargs != 1 else "")
        return name if self.required else f"[{name}]"


_built: list[Any] = []
"""The click command tree of ``app``, built by the first :func:`main` of the process."""


def _command() -> Any:
    """``app`` as a click command with the polished help, built once per process.

    A build costs ~0.1 s of CPU and tests call :func:`main` hundreds of times; a click command keeps no state
    between invocations.
    """
    if not _built:
        command = typer.main.get_command(app)
        _polish_help(command)
        _interrupt_parsing_too(command)
        _built.append(command)
    return _built[0]


def _interrupt_parsing_too(command: Any) -> None:
    """A signal while the command line is parsed (or a command is looked up) ends with the interrupted line too.

    typer turns a ``KeyboardInterrupt`` outside the command functions (which :func:`_interruptible` wraps) into a
    silent exit 130; parsing imports pydantic on first use, so a Ctrl-C, SIGTERM or SIGHUP there was common.
    """
    for name in ("make_context", "invoke"):
        original = getattr(command, name)

        def wrapper(*args: Any, __original: Callable[..., Any] = original, **kwargs: Any) -> Any:
            try:
                return __original(*args, **kwargs)
            except KeyboardInterrupt as exc:
                entry.quiet_after_interrupt()
                raise _interrupt_error(exc) from None

        setattr(command, name, wrapper)


class _CoercionWhenGiven:
    """typer's value coercion of one parameter, built when a value comes.

    typer builds it on the parameter's first parse even for None (an option not given, a group's ``--help``), and
    the first one imports pydantic (~0.1 s of CPU; a help page needs none). None gives what typer's own
    ``RuntimeParam.coerce`` gives for it (``tests/foundation/test_cli_lazy.py`` compares them).
    """

    def __init__(self, build: Callable[[], Any]) -> None:
        self._build = build
        self._built: Any = None

    def coerce(self, value: Any, param: Any, ctx: Any) -> Any:
        if value is None:
            return () if param.multiple or param.nargs == -1 else None
        if _is_empty_path(value, param):
            raise UsageError(
                f"{_param_label(param)}: an empty path (an unset shell variable?); give a file or folder name"
            )
        if self._built is None:
            self._built = self._build()
        return self._built.coerce(value, param=param, ctx=ctx)


def _takes_paths(param: Any) -> bool:
    """The parameter's annotation is a path (``Path``, ``Path | None``, ``list[Path]``)."""
    annotation = getattr(getattr(param, "type_descriptor", None), "annotation", None)
    if annotation is None:
        return False
    if annotation is Path:
        return True
    return any(a is Path or getattr(a, "__args__", None) == (Path,) for a in getattr(annotation, "__args__", ()))


def _is_empty_path(value: Any, param: Any) -> bool:
    """``value`` (one or several given) holds an empty string for a path parameter, which typer reads as ``.``."""
    values = value if isinstance(value, list | tuple) else (value,)
    return any(isinstance(v, str) and not v.strip() for v in values) and _takes_paths(param)


def _param_label(param: Any) -> str:
    """How the user names the parameter: its longest option (``--urdf``) or its metavar (``SRC``)."""
    opts = getattr(param, "opts", None) or []
    if opts and str(opts[0]).startswith("-"):
        return str(max(opts, key=len))
    return str(getattr(param, "metavar", None) or getattr(param, "name", "") or "an argument").upper()


def _coerce_when_given(param: Any) -> None:
    build = getattr(param, "get_runtime_param", None)
    if build is not None and not isinstance(getattr(param, "_robocal_coercion", None), _CoercionWhenGiven):
        param._robocal_coercion = coercion = _CoercionWhenGiven(build)
        param.get_runtime_param = lambda: coercion


def _polish_help(command: Any) -> None:
    """Flags without ``<bool>`` (``--help`` too), positionals as ``SRC DST``, for every command of the tree."""
    for param in command.params:
        if isinstance(param, TyperOption) and (param.is_flag or param.is_bool_flag):
            param.__class__ = _FlagOption
        elif isinstance(param, TyperArgument):
            param.__class__ = _PositionalArgument
            if param.metavar is None and param.name:
                param.metavar = param.name.upper()
        _coerce_when_given(param)
    original = command.get_help_option

    def get_help_option(ctx: Any) -> Any:
        option = original(ctx)
        if isinstance(option, TyperOption) and not isinstance(option, _FlagOption):
            option.__class__ = _FlagOption
        _coerce_when_given(option)
        return option

    command.get_help_option = get_help_option
    for sub in (getattr(command, "commands", None) or {}).values():  # typer vendors click: duck-type groups
        _polish_help(sub)


def _version_needs_no_value(args: Sequence[str]) -> None:
    """``robocal --version true``: --version is a flag; refuse anything after it instead of ignoring it."""
    if args and args[0] == "--version" and len(args) > 1:
        raise UsageError(f"--version takes no value and no other arguments (got {' '.join(args[1:])!r})")


def _crash_log_dirs() -> list[Path]:
    state = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return [Path(state) / "robocal", Path(tempfile.gettempdir())]


def _report_bug(exc: BaseException, args: Sequence[str]) -> int:
    """Save the traceback of an unexpected exception to a log file and print one ``error:`` line naming it.

    Returns:
        :data:`~robocal.cli._common.EXIT_BUG` (70, ``EX_SOFTWARE``).
    """
    stamp = time.strftime("%Y%m%d-%H%M%S")
    text = "".join(
        [
            f"robocal {__version__} on Python {platform.python_version()} ({platform.platform()})\n",
            f"command: robocal {shlex.join(args).encode('ascii', 'backslashreplace').decode()}\n\n",
            *traceback.format_exception(type(exc), exc, exc.__traceback__),
        ]
    )
    saved: Path | None = None
    for folder in _crash_log_dirs():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd, name = tempfile.mkstemp(prefix=f"robocal-crash-{stamp}-", suffix=".log", dir=folder)
            with os.fdopen(fd, "w", encoding="utf-8", errors="backslashreplace") as fh:
                fh.write(text)
            saved = Path(name)
            break
        except OSError:
            continue
    what = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    where = f"the traceback is in {saved}" if saved is not None else "the traceback could not be saved"
    _common.print_error(f"internal error, a bug in robocal ({what}); {where}; please report it")
    return _common.EXIT_BUG


def _closed_pipe() -> int:
    """Standard output was closed by the reader (``| head``): stop quietly, like other command-line tools."""
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    return _common.EXIT_PIPE


def run() -> None:
    """Console-script wrapper of older installs (``robocal.cli.entry.run`` is the entry point now)."""
    entry.run_command(main)
