"""Universal Robots: DH from the controller → exact per-joint transforms → ur_description's kinematics YAML.

Entry points: :mod:`job` (``robocal ur extract / correct / defaults / plot``) and :mod:`verify` (the DH FK
against an independent URDF FK).
"""
