"""The far-point paper's own numbers (Fujii, Ohya, Tsubouchi; docs/papers.md section B), in one place.

Its Figs 7, 8, 10 and 11 are plots without printed values; these are the numbers its text
states. Everything the reproduction chose itself lives in :mod:`.experiment`, and what the
world and the localizers ship with is read from their configs (:mod:`.world`).
"""

from __future__ import annotations

# ------------------------------------------------------------------------------------ the run

SPEED_MPS = 0.15  # the robot's speed on the square path
LAPS = 3  # laps of the square per run
UPDATE_TRAVEL_M = 0.5  # the MCL localizes every 0.5 m of travel
ESTIMATES = 63  # estimates in its one run per parameter value
LIDAR_HEIGHT_M = 0.2  # the scanning height of the LIDAR under test (it sees legs)
REFERENCE_LIDAR_HEIGHT_M = 1.9  # the second LIDAR, above the crowd, that gave the reference pose

# ------------------------------------------------------------------------------------ the sweeps

#: Figs 7/8: the sampling parameter (multiplier of the motion model's alphas), 0.1 to 1.0
SAMPLINGS = tuple(round(0.1 * k, 1) for k in range(1, 11))
#: Figs 10/11: the sd of the hit Gaussian [m], 0.1 to 1.0, at sampling ``HIT_SWEEP_SAMPLING``
HITS = tuple(round(0.1 * k, 1) for k in range(1, 11))
HIT_SWEEP_SAMPLING = 0.1

# ------------------------------------------------------------------------------------ failures

FAIL_M = 1.0  # a failure is an estimate >= 1 m from the reference
LARGE_FAIL_M = 3.0  # its large failures: "> 3 m, ~90 deg off"
LARGE_FAIL_HEADING_DEG = 90.0

# ------------------------------------------------------------------------------------ its findings

SAMPLING_THRESHOLD = 0.6  # raw MCL's error and failures grow from here up
HIT_THRESHOLD = 0.8  # raw MCL fails from here up
RAW_FAILURES_AT_HIT_THRESHOLD = 2  # of its 63 estimates, each > 3 m and ~90 deg off
FAR_FAILURES_AT_HIT_THRESHOLD = 0
POINTS_PER_WINDOW = 100_000  # points accumulated over 0.5 m
EXTRACTION_S = 0.06  # seconds of one far-point extraction over them
