"""``python -m robocal`` runs the CLI (signal handlers first: see :mod:`robocal.cli.entry`)."""

from robocal.cli.entry import run

run()
