"""``robocal sim``: the simulators served as devices other software can open (entry points in :mod:`job`)."""
