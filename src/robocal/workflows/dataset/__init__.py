"""LeRobot datasets: the jobs behind ``robocal dataset`` (entry points in :mod:`job`).

The Parquet engine itself is the public :mod:`robocal.dataset` package; this folder orchestrates it.
"""
