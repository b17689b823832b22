"""Helpers shared by the CLI modules: consoles, exit codes, small argument parsers."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from rich.console import Console
from rich.table import Table

from ..errors import UsageError

EXIT_OK = 0
EXIT_WARNINGS = 1
EXIT_BAD_INPUT = 2
EXIT_DEVICE = 3
EXIT_BUG = 70
"""An unexpected exception: a bug in robocal (BSD ``EX_SOFTWARE``); the traceback is saved to a log file."""
EXIT_INTERRUPTED = 130
EXIT_PIPE = 141
"""Standard output was closed early (``robocal ... | head``), like a shell's 128 + SIGPIPE."""


def interrupt_exit_code(exc: BaseException) -> int:
    """128 + the signal that ended the command (an :class:`~robocal.errors.SignalInterrupt`), else 130 (Ctrl-C)."""
    code = getattr(exc, "exit_code", EXIT_INTERRUPTED)
    return code if isinstance(code, int) and 129 <= code <= 159 else EXIT_INTERRUPTED


class FitConsole(Console):
    """A console that, when it is not a terminal (piped, CI), prints tables at their full width.

    rich lays out for 80 columns without a terminal and cuts cells (``left_s…``); a log must keep whole names.
    On a terminal the terminal's width is used as usual.
    """

    def print(self, *objects: Any, **kwargs: Any) -> None:
        tables = [o for o in objects if isinstance(o, Table)]
        if not tables or self.is_terminal:
            super().print(*objects, **kwargs)
            return
        wide = self.options.update_width(1 << 16)
        need = max(self.measure(t, options=wide).maximum for t in tables)
        saved = self._width
        self.width = max(need, self.width)  # rich caps print(width=) at the console's width
        try:
            super().print(*objects, **kwargs)
        finally:
            self._width = saved

    def on_broken_pipe(self) -> None:
        """A closed output pipe (``robocal ... | head``) exits 141, not rich's 1 (which means "warnings")."""
        if self.quiet:
            return
        with contextlib.suppress(OSError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        raise SystemExit(EXIT_PIPE)


console = FitConsole(highlight=False, soft_wrap=True)
"""Standard output console for results."""
err_console = FitConsole(stderr=True, highlight=False, soft_wrap=True)
"""Standard error console for warnings and progress."""


def print_error(message: str) -> None:
    """Print one ``error:`` line (no markup, no traceback) to standard error."""
    line = (
        " ".join(str(message).split("\n")[0:1])
        if "\n" not in str(message)
        else str(message).replace("\n", "; ")
    )
    sys.stderr.write(f"error: {line}\n")
    sys.stderr.flush()


def print_warning(message: str) -> None:
    """Print one ``warning:`` line to standard error."""
    sys.stderr.write(f"warning: {message}\n")
    sys.stderr.flush()


def parse_csv_list(value: str | None, what: str = "list") -> list[str] | None:
    """Split ``"a,b,c"`` into names; ``None`` stays ``None``. Empty items are an error."""
    if value is None:
        return None
    items = [v.strip() for v in value.split(",")]
    if not items or any(not v for v in items):
        raise UsageError(f"{what} {value!r}: expected comma-separated names with no empty entries")
    return items


def parse_assignments(value: str | None, what: str) -> dict[str, str]:
    """Parse ``"a=x,b=y"`` into ``{"a": "x", "b": "y"}``; ``None`` (the option not given) is ``{}``.

    Raises:
        UsageError: An empty value (``--modes ""`` is not "no override") or an item that is not ``name=value``.
    """
    if value is None:
        return {}
    out: dict[str, str] = {}
    for item in value.split(","):
        key, sep, val = item.partition("=")
        if not sep or not key.strip() or not val.strip():
            raise UsageError(f"{what} {value!r}: expected name=value pairs separated by commas")
        out[key.strip()] = val.strip()
    return out


_T = TypeVar("_T")


def parse_typed_assignments(
    value: str | None, what: str, convert: Callable[[str], _T], expected: str
) -> dict[str, _T]:
    """:func:`parse_assignments` with each value converted; ``what name=value: expected`` when it does not convert."""
    out: dict[str, _T] = {}
    for key, text in parse_assignments(value, what).items():
        try:
            out[key] = convert(text)
        except ValueError:
            raise UsageError(f"{what} {key}={text}: {expected}") from None
    return out


PLAIN_TABLE_ROWS = 200
"""Tables with more rows are printed as plain aligned text: rich lays out a table in ~1 ms per row."""


def print_plain_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
    """Print rows as plain left-aligned columns (two spaces apart), in time linear in the row count."""
    widths = [len(h) for h in headers]
    for row in rows:
        for i, cell in enumerate(row[:-1]):
            widths[i] = max(widths[i], len(cell))
    out = sys.stdout
    for row in (headers, *rows):
        cells = [cell.ljust(widths[i]) for i, cell in enumerate(row[:-1])]
        out.write("  ".join([*cells, row[-1]]).rstrip() + "\n")
    out.flush()


def exit_code_for(warnings: Sequence[object]) -> int:
    """0 when there were no warnings, else 1."""
    return EXIT_WARNINGS if warnings else EXIT_OK


def print_warnings(warnings: Sequence[str]) -> int:
    """Print each warning as one ``warning:`` line; return the exit code (0 without warnings, else 1)."""
    for w in warnings:
        print_warning(w)
    return exit_code_for(warnings)
