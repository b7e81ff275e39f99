"""The candidate-set paper's own numbers, in one place; everything else in the report is ours.

Motomura, Matsuoka, Hasegawa, Kurazume, "Real-time self-localization method by using
measurements of directions of two landmarks and dead reckoning", JRSJ; Tables 1-3 as restated
in docs/papers.md section A.
"""

from __future__ import annotations

#: A table row: position (mean, sd) in mm and heading (mean, sd) in degrees.
PaperRow = tuple[tuple[float, float], tuple[float, float]]

#: Tables 1-3 (statistics from the first fix of method (5) on), by experiment and method key.
PAPER: dict[str, dict[str, PaperRow]] = {
    "exp1": {
        "kalman": ((383.0, 298.0), (21.6, 30.6)),
        "mcl_bearing_paper": ((381.0, 356.0), (40.1, 55.0)),
        "candidate_sets": ((100.0, 87.0), (0.7, 1.2)),
    },
    "exp2": {
        "kalman": ((333.0, 163.0), (24.8, 23.4)),
        "mcl_bearing_paper": ((133.0, 129.0), (6.9, 8.0)),
        "candidate_sets": ((125.0, 74.0), (2.7, 4.0)),
    },
    "exp3": {
        "candidate_sets_k1": ((157.0, 89.0), (4.8, 11.7)),
        "candidate_sets_k5": ((135.0, 78.0), (3.0, 9.1)),
        "candidate_sets": ((125.0, 74.0), (2.7, 4.0)),
    },
}
PAPER_FIRST_FIX_MM = 806.0  # Exp 1, distance travelled before method (5) first fixed its pose
PAPER_SPEED_MPS = (1.753, 0.941)  # Exp 2 field robot, maximum and mean speed
