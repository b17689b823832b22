"""``robocal ur`` commands."""

from __future__ import annotations

import typer

app = typer.Typer(help="ur commands.", no_args_is_help=True)
