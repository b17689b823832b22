"""Auto-calibration: the robot finds its own hard stops at a capped torque.

Entry points: :mod:`job` (``robocal sweep --auto`` / ``demo --auto``) and :mod:`sweep` (the joints' guarded
searches, one joint in :mod:`joint`); :mod:`group` orders joints, :mod:`model` holds the shared values (clock,
joint driver protocol), the joint drivers (each vendor's registers as the driver protocol) live in the vendors'
homes, ``backends/<vendor>/joint_driver.py``, found through :func:`model.joint_driver_class`, :mod:`sim` builds the simulated arms the tests and demos run against.
"""
