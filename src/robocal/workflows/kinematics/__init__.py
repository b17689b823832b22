"""Kinematic identification of hobby arms: plan poses, record, fit link corrections, judge, export.

Entry points: :mod:`job` (``robocal kinematics identify`` / ``simulate``), :mod:`plan` and :mod:`plan_images`
(``kinematics plan``), :mod:`record` / :mod:`record_arm` (``kinematics record``), :mod:`vision` (tag images).
Each job takes one frozen request (:mod:`request` for the identifiers, the others beside their job). The fit is
:mod:`fit`; what a fit may claim is decided by :mod:`gates` and :mod:`plausibility` (:mod:`image_gates` for tag
images); :mod:`report` and :mod:`export` write the results; :mod:`sim` and :mod:`vision_sim` make simulated
measurements.
"""
