"""Particle filters that know when they are lost: kidnapping, one landmark in view,
swapped landmark ids, an odometry jump, blocked scans. Driven by tests/localizers/lost.py; the
figures behind the bounds: ``python -m tests.localizers.lost_figures``. "Without them" in a comment: the
figures of the same filter without what it has for knowing when it is lost (ours: lost detection,
recovery, ``max_spread_m``)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.localizers.lost import (
    EVENT_S,
    MCL_RUN,
    ROOM,
    ROOM_KW,
    STATIC,
    drive,
    odometry_jump,
    one_landmark,
    swapped,
    zero_scans,
)

KIDNAP_STEP_BEARING, KIDNAP_STEP_ROOM = 301, 401  # the first step after t = 10 s at 30 Hz, at 40 Hz


def test_one_landmark_in_view_claims_no_pose() -> None:
    # without lost detection: 888 of 10,000 steps claimed, 860 of them 1-12 m off at a spread of 0.29 m
    run = drive("mcl_bearing", STATIC, 3000, 0, policy="random_walk", frame=one_landmark())
    assert run.wrong_claims() == 0


@pytest.mark.parametrize("name", ["mcl_bearing_paper", "mcl_bearing"])
def test_swapped_landmark_ids_claim_no_wrong_pose(name: str) -> None:
    # without them: mcl_bearing_paper claims every step, 1628 of 1800 more than 1 m off
    run = drive(name, STATIC, 900, 0, policy="random_walk", frame=swapped())
    assert run.wrong_claims() <= 9, run.wrong_claims()


@pytest.mark.parametrize(("name", "recovered_at_least", "longest_s"), [("mcl_bearing", 5, 9.0), ("mcl_bearing_paper", 4, 12.0)])
def test_bearing_filters_relocalize_after_a_kidnapping(name: str, recovered_at_least: int, longest_s: float) -> None:
    # measured (10 seeds, random walk, < 0.2 m within 30 s): mcl_bearing 5/10 (6/10 with max_spread_m 1 m), median 14.6 s;
    # mcl_bearing_paper 4/10, median 16.3 s (without them: 5/10 and 4/10, with 3546 and 7331 claims > 1 m off)
    times, longest = [], 0.0
    for seed in range(10):
        run = drive(name, STATIC, 1200, seed, policy="random_walk", kidnap_at=KIDNAP_STEP_BEARING, **MCL_RUN)
        times.append(run.recovery_s(0.2))
        longest = max(longest, run.longest_wrong_s())
    assert sum(t <= 30.0 for t in times) >= recovered_at_least, times
    # no long stretch of confident wrong poses (without them: up to 8.5 s and 30 s); the paper's filter
    # dead-reckons from its last pose when every particle is deleted (paper sec. 5 (4)): up to 11.3 s.
    # mcl_bearing: up to 8.5 s. Its lost test compares the bearings with the estimate; with two
    # landmarks in view (75 % of the static field's frames) a wrong pose on the circle through them
    # fits them exactly, which no bearing test can see. (Gating on augmented MCL's w_fast/w_slow
    # instead gave 2.5 s, but in a crowd it withheld half the poses of a well-localized filter.)
    assert longest <= longest_s, longest


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "params", "recovered_at_least", "longest_s"),
    [
        ("mcl_lidar", {}, 4, 6.0),  # recovery is on by default (ours)
        ("far_point_mcl", {}, 4, 20.0),
        ("mcl_lidar", {"recovery": False}, 0, 6.0),  # the paper's plain MCL
        ("far_point_mcl", {"mcl": {"recovery": False}}, 0, 6.0),
    ],
)
def test_lidar_filters_after_a_kidnapping(name: str, params: dict, recovered_at_least: int, longest_s: float) -> None:
    # In the room (crowd of 4, circle), "recovered": < 0.3 m. Measured on 10 seeds: with
    # recovery 7/10 (mcl_lidar) and 8/10 (far_point_mcl); the paper's plain MCL does not recover
    # but stops claiming a pose within 5 s (without them: 5/10 and 2/10, with up to 30 s of wrong claims).
    times, longest = [], 0.0
    for seed in range(6):
        run = drive(name, ROOM, 1600, seed, localizer_params=params, kidnap_at=KIDNAP_STEP_ROOM, **MCL_RUN, **ROOM_KW)
        times.append(run.recovery_s(0.3))
        longest = max(longest, run.longest_wrong_s())
    assert sum(t <= 30.0 for t in times) >= recovered_at_least, times
    assert longest <= longest_s, longest


#: a 10 m odometry jump at t = 10 s: two 5 m forward increments the robot does not make
jump = odometry_jump(5.0, (KIDNAP_STEP_ROOM, KIDNAP_STEP_ROOM + 1))


@pytest.mark.parametrize(("name", "params"), [("mcl_lidar", {"recovery": True}), ("far_point_mcl", {"mcl": {"recovery": True}})])
def test_lidar_recovery_after_a_10_m_odometry_jump(name: str, params: dict) -> None:
    # without them: 1.4-1.5 m off at the end, every step claimed
    run = drive(name, ROOM, 1600, 0, localizer_params=params, odometry=jump, event_s=EVENT_S, **MCL_RUN, **ROOM_KW)
    assert run.valid[-40:].all() and np.nanmax(run.error_m[-40:]) < 0.2
    assert run.longest_wrong_s() <= 6.0


def test_plain_lidar_mcl_stops_claiming_after_a_10_m_odometry_jump() -> None:
    # without them: 3.3 m off at the end, claimed with a spread of 0.00 m
    run = drive("mcl_lidar", ROOM, 1600, 0, odometry=jump, **MCL_RUN, **ROOM_KW)
    assert run.wrong_claims() == 0


#: all-zero scans (a blocked sensor) after 10 s to 20 s
zeros = zero_scans(401, 801)


@pytest.mark.parametrize("name", ["mcl_lidar", "far_point_mcl"])
def test_blocked_scans_do_not_move_the_lidar_filters(name: str) -> None:
    # without them: mcl_lidar 1128 claims > 1 m off (2.1 m after 30 s of good scans with recovery)
    run = drive(name, ROOM, 2000, 0, frame=zeros, **MCL_RUN, **ROOM_KW)
    assert run.wrong_claims() == 0
    assert np.nanmax(run.error_m[-40:]) < 0.2
