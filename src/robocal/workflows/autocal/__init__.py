"""Auto-calibration: the robot finds its own hard stops at a capped torque.

Entry points: :mod:`job` (``robocal sweep --auto`` / ``demo --auto``) and :mod:`sweep` (the joints' guarded
searches, one joint in :mod:`joint`); :mod:`group` orders joints, :mod:`model` holds the shared values (clock,
joint driver protocol), :mod:`servo_driver` / :mod:`robstride_driver` turn each vendor's registers into the
driver protocol, :mod:`sim` builds the simulated arms the tests and demos run against.
"""
