"""The ``robocal`` command line: a thin typer layer over :mod:`robocal.workflows`."""

from .entry import protect_startup_if_program

protect_startup_if_program()  # an older console script imports cli.main directly: cover its slow imports too
