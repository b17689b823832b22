"""The Robstride / Lite hard-stop sweep and the calibrated robot at run time.

Entry points: :func:`job.run_sweep` (``robocal sweep``: validate, sample a source, bisect, write),
:mod:`power_on_check` (``robocal check --source``: the first reading and its 2π branch) and :mod:`robot`
(read / write a calibrated robot in the joint frame). Sampling lives in :mod:`session`, writing in :mod:`output`
and :mod:`interrupts`, the joint list from URDF + profile in :mod:`joint_specs`.
"""
