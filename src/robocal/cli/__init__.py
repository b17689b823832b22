"""The ``robocal`` command line: a thin typer layer over :mod:`robocal.workflows`."""
