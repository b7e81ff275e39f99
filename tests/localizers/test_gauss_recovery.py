"""Localizers that know when they are lost: kidnapping, blind coasting, one landmark,
an odometry jump, for dead_reckoning, resection, kalman and candidate_sets. The figures the
bounds come from: ``python -m tests.localizers.lost_figures gauss_coast gauss_one_landmark gauss_kidnap gauss_odometry_jump``.
"Without them" in a comment: the figures of the same localizer without what it has for knowing when it
is lost (ours; each module's docstring)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.localizers.lost import CROWDED, EVENT_S, GAUSS_KIDNAP, STATIC, drive, no_landmarks, odometry_jump, one_landmark

CROWDED_KW = {"crowd_size": 3}
SEEDS = range(10)


@pytest.mark.parametrize(("name", "within_s"), [("kalman", 12.0), ("candidate_sets", 10.0), ("resection", 5.0)])
def test_a_kidnapped_robot_is_found_again(name: str, within_s: float) -> None:
    # circle in the crowded field, kidnapped (>= 2 m) at 10 s; measured (10 seeds), recovered
    # (error < 0.2 m for 1 s) after: kalman 0.5-10 s, candidate_sets 0-8 s, resection 0-4.9 s;
    # valid estimates more than 1 m off for at most 0.5 s (kalman: the 15 rejected fixes), 0.2 s, 0 s
    runs = [drive(name, CROWDED, 1200, s, **GAUSS_KIDNAP, **CROWDED_KW) for s in SEEDS]
    recovered = [r.recovery_s(hold_s=1.0) <= within_s for r in runs]
    assert sum(recovered) >= len(runs) - 1, f"{name}: recovered within {within_s} s on {sum(recovered)}/{len(runs)} seeds"
    wrong = [r.longest_wrong_s() for r in runs]
    assert max(wrong) <= 1.0, f"{name}: valid estimates more than 1 m off for {wrong} s"


def test_dead_reckoning_stops_claiming_a_pose_it_cannot_know() -> None:
    # it cannot notice a kidnapping: its spread passes max_spread_m (1 m) 10-25 s after it on the
    # random walk (measured; on the gentle circle it takes longer than the 30 s of the run)
    for s in SEEDS[:6]:
        r = drive("dead_reckoning", CROWDED, 1200, s, policy="random_walk", **GAUSS_KIDNAP, **CROWDED_KW)
        assert not r.valid[-1], f"seed {s}: still claims a pose, error {r.error_m[-1]:.2f} m"
        assert r.spread_m[r.valid].max() <= 1.0


def test_candidate_sets_drop_a_contradicted_pose_on_the_static_field() -> None:
    # random walk on the static field (it also drives into walls, where the odometry goes on
    # counting): valid estimates are more than 1 m off for up to 6.9 s (without them: 30.6 s)
    runs = [drive("candidate_sets", STATIC, 1200, s, policy="random_walk", **GAUSS_KIDNAP) for s in range(10)]
    wrong = [r.longest_wrong_s() for r in runs]
    assert max(wrong) <= 10.0, wrong


def test_candidate_sets_widen_while_blind_for_333_s() -> None:
    free = drive("candidate_sets", STATIC, 10290, frame=no_landmarks(300), localizer_params={"max_spread_m": math.inf})
    blind = free.window(10.0)
    assert free.valid[blind].all()
    spread = free.spread_m[blind]
    assert (np.diff(spread) >= -1e-12).all() and spread[-1] > 10 * spread[0]
    assert free.outside_3sd(blind) <= 0.01  # without them: 0.91 (spread 0.088 m while 2.8 m off)
    limited = drive("candidate_sets", STATIC, 10290, frame=no_landmarks(300))
    assert not limited.valid[-1] and (limited.spread_m[limited.valid] <= 1.0).all()


def test_kalman_with_one_landmark_is_not_overconfident() -> None:
    r = drive("kalman", STATIC, 2100, frame=one_landmark(300), localizer_params={"max_spread_m": math.inf})
    assert r.outside_3sd(r.window(10.0)) <= 0.05  # without them: 0.88


def test_kalman_recovers_from_a_10_m_odometry_jump() -> None:
    r = drive("kalman", STATIC, 1200, odometry=odometry_jump(10.0, (300,)), event_s=EVENT_S)
    assert r.recovery_s(hold_s=1.0) <= 2.0  # measured 0.6 s (without them: 3.4 m off after 30 s)
    assert r.error_m[-1] < 0.2
