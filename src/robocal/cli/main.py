"""Entry point of the ``robocal`` command.

Exit codes: 0 success, 1 finished with warnings, 2 bad input or usage (one ``error:`` line, nothing
written), 3 device or communication failure, 130 interrupted.
"""

from __future__ import annotations

import functools
import logging
import sys
from collections.abc import Callable, Sequence
from typing import Any

import typer

from .. import __version__
from ..errors import CalibError
from . import _common

app = typer.Typer(
    name="robocal",
    help="Calibrate robots: Robstride joints, LeRobot arms, Universal Robots kinematics.",
    no_args_is_help=True,
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
    """Ctrl-C reached the CLI without the command handling it."""

    exit_code = 130


def _interruptible(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn a stray KeyboardInterrupt into an ``error: interrupted`` line (typer would exit 130 silently)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except KeyboardInterrupt:
            raise UserInterruptError("interrupted") from None

    return wrapper


def _wrap_commands(typer_app: typer.Typer) -> None:
    for info in typer_app.registered_commands:
        if info.callback is not None:
            info.callback = _interruptible(info.callback)
    for group in typer_app.registered_groups:
        if group.typer_instance is not None:
            _wrap_commands(group.typer_instance)


def _register() -> None:
    from . import dataset, demo, files, kinematics, lerobot, sim, sweep, ur

    files.register(app)
    sweep.register(app)
    demo.register(app)
    app.add_typer(lerobot.app, name="lerobot")
    app.add_typer(ur.app, name="ur")
    app.add_typer(dataset.app, name="dataset")
    app.add_typer(kinematics.app, name="kinematics")
    app.add_typer(sim.app, name="sim")
    _wrap_commands(app)


_register()


class _NoteHandler(logging.Handler):
    """Print library notes (e.g. a write through a symbolic link) as ``note:`` lines on standard error."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"note: {record.getMessage()}\n")
        sys.stderr.flush()


def _install_note_handler() -> None:
    logger = logging.getLogger("robocal.fileio")
    if not any(isinstance(h, _NoteHandler) for h in logger.handlers):
        logger.addHandler(_NoteHandler(logging.INFO))
    logger.setLevel(logging.INFO)
    logger.propagate = False


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit code (also used as the console-script entry point).

    Args:
        argv: Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns:
        The process exit code.
    """
    _install_note_handler()
    command = typer.main.get_command(app)
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        rv = command.main(args=args, prog_name="robocal", standalone_mode=False)
    except CalibError as exc:
        _common.print_error(str(exc))
        return exc.exit_code
    except KeyboardInterrupt:
        _common.print_error("interrupted")
        return 130
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
        raise
    if isinstance(rv, int):
        return rv
    return 0


def run() -> None:
    """Console-script wrapper: ``sys.exit(main())``."""
    sys.exit(main())
