"""``python -m robocal`` runs the CLI."""

from robocal.cli.main import run

run()
