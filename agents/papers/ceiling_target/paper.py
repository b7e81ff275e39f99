"""The ceiling-target paper's own numbers (Fukaya, Takeda, Okura; docs/papers.md section C), in one place."""

from __future__ import annotations

#: Table 2: set rotation -> measured rotation [deg], the robot under the target (X_R = Y_R = 0)
TABLE2_ROTATION_DEG = {
    0: 0,
    30: 36,
    60: 65,
    90: 91,
    120: 116,
    150: 146,
    180: 181,
    210: 216,
    240: 245,
    270: 270,
    300: 296,
    330: 325,
    360: 360,
}
#: Table 3: set X_R -> measured X_R [cm] (theta = 0, Y_R = 0); X across the corridor
TABLE3_X_CM = {-25: -23, -20: -19, -15: -14, -10: -8, -5: -3, 0: 1, 5: 6, 10: 12, 15: 17, 20: 22, 25: 27}
#: Table 4: set Y_R -> measured Y_R [cm] (theta = 0, X_R = 0); Y along the corridor
TABLE4_Y_CM = {-15: -18, -10: -12, -5: -6, 0: 1, 5: 6, 10: 12, 15: 18}

#: its claim from Tables 2-4
ROTATION_WITHIN_DEG = 6.0
POSITION_WITHIN_CM = 3.0

#: the drive: targets along the corridor [m]; Table 5 (no correction) at target 3, Table 6 (corrected) at each
DRIVE_TARGETS_M = (6.9, 13.9, 20.8)
TABLE5_AT_TARGET3_CM = (0, -45)  # (X, Y): the sonar keeps X; Y is 45 cm short
TABLE6_CM = {6.9: (-3, -6), 13.9: (-1, -2), 20.8: (-1, -3)}
