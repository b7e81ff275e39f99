"""The far-landmark stereo paper's own numbers (docs/papers.md section D), in one place.

Its Figs 8-10 are plots without printed values; these are the numbers its text states. What
the reproduction chose itself lives in :mod:`.experiment`; what the world and the localizers
ship with is read from their configs (:mod:`.world`).
"""

from __future__ import annotations

import math

# ------------------------------------------------------------------------------------ the method (sec. 2, 3.1)

PARTICLES = 500  # particles spread around the initial pose
SECTOR_RAD = math.radians(30.0)  # far emphasis: the bearing range cut into 30 deg sectors
MIN_RANGE_M = 3.0  # landmarks nearer than 3 m are never used
EDGE_TYPES = 30  # 3 channels x 5 heights x 2 polarities
BASELINE_M = 0.19  # between neighbouring cameras of the trinocular rig

# ------------------------------------------------------------------------------------ the experiment (sec. 3)

ROUTE_M = 100.0  # "about 100 m": straight, a right turn, straight up to a building
RUNS = 2  # driven twice at the same time of day: run 1 makes the map, run 2 is localized
PLOT_PERIOD_S = 1.0  # Figs 8-9: one mark per second ...
PLOT_GRID_M = 1.0  # ... on a 1 m grid

# ------------------------------------------------------------------------------------ its findings (sec. 3.2)

MAX_DIFFERENCE_M = 0.7  # Fig. 10: at most about 0.7 m between its estimate and amcl's
#: its stated weak spot: the estimate drifts where few landmarks are detected and is pulled back
#: once good ones are detected again (no number given)
WEAK_SPOT = "drift where few landmarks are detected, corrected once good ones are detected again"
#: its stated next step (sec. 4): crowded places, where the LIDAR method is weak
NEXT_STEP = "crowds, where the conventional (LIDAR) method is weak"
