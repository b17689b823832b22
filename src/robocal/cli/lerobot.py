"""``robocal lerobot`` commands."""

from __future__ import annotations

import typer

app = typer.Typer(help="lerobot commands.", no_args_is_help=True)
