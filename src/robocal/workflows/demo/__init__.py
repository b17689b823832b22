"""``robocal demo``: every demo end to end on the simulators.

Entry points: :mod:`job` (the default demo, the UR demo), :mod:`auto` and :mod:`auto_arm` (``demo --auto``),
:mod:`identify` (``demo --identify``).
"""
