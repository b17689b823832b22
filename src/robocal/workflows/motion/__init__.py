"""The motion guard every command that moves a motor or changes a register runs inside.

:class:`guard.MotionGuard` makes every motor limp and writes back every changed register on a signal, an
exception or a lost device; :mod:`snapshot` keeps the state file ``lerobot restore-previous`` reads.
"""
