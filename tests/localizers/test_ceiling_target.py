"""The ceiling-target pipeline and localizer: HSV, learned thresholds, round trips, bad input."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import envs  # noqa: F401  (registers the ids)
from agents.papers.ceiling_target.fit import FitPlan, camera_json, fit, inside, labelled_images
from core.schema import ConfigError
from envs.features.ceiling import LABEL_LIGHT, LABEL_SIGN, PALETTE, CeilingConfig, colour_label
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import IDEAL, CeilingCamera
from localizers.base import MeasurementError, OdometryDelta, PoseEstimate
from localizers.ceiling_target import CeilingImage, CeilingTargetLocalizer
from localizers.ceiling_target.vision import (
    CameraIntrinsics,
    CeilingPlan,
    ColourRange,
    cell_points,
    fit_colour_range,
    hsv8,
    paper_hsv,
)
from localizers.registry import load_params, make_localizer

CLEAN = IDEAL  # every imperfection of the camera off


def _setup(**camera: object) -> tuple[LocalizationEnv, CeilingCamera, CameraIntrinsics, CeilingTargetLocalizer]:
    env = LocalizationEnv("ceiling_corridor", camera=camera or None)
    cam = env.sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    loc = make_localizer("ceiling_target", env.landmark_map, dt_s=env.config.dt_s)
    assert isinstance(loc, CeilingTargetLocalizer)
    return env, cam, CameraIntrinsics.from_metadata(cam.metadata()), loc


# ---------------------------------------------------------------------------- HSV
def test_paper_hsv_edge_cases() -> None:
    cases = {
        (0.0, 0.0, 0.0): (0.0, 0.0, 0.0),  # V = 0: S = 0, H undefined (0)
        (0.5, 0.5, 0.5): (0.0, 0.0, 0.5),  # grey: S = 0
        (1.0, 0.0, 0.0): (0.0, 1.0, 1.0),  # R max
        (0.0, 1.0, 0.0): (1 / 3, 1.0, 1.0),  # G max: H = 2 / 6
        (0.0, 0.0, 1.0): (2 / 3, 1.0, 1.0),  # B max: H = 4 / 6
        (1.0, 0.0, 0.5): (1 - 0.5 / 6, 1.0, 1.0),  # R max, B > G: H < 0 wraps by + 1
        (0.8, 0.4, 0.2): ((0.4 - 0.2) / 0.6 / 6, 0.75, 0.8),
    }
    for rgb, hsv in cases.items():
        assert paper_hsv(np.array(rgb)) == pytest.approx(hsv, abs=1e-12), rgb


def test_opencv_hsv_equals_the_paper_formulas_after_scaling() -> None:
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, size=(200, 200, 3), dtype=np.uint8)
    edges = np.array(
        [[0, 0, 0], [128, 128, 128], [255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 0, 128], [255, 255, 255]], np.uint8
    )
    rgb[0, : len(edges)] = edges
    ours = paper_hsv(rgb / 255.0)
    cv = hsv8(rgb).astype(np.float64) / [256.0, 255.0, 255.0]
    dh = np.abs((cv[..., 0] - ours[..., 0] + 0.5) % 1.0 - 0.5)  # hue is circular
    defined = ours[..., 1] > 0  # hue is undefined for greys
    assert dh[defined].max() <= 1.0 / 256 + 1e-9
    assert np.abs(cv[..., 1:] - ours[..., 1:]).max() <= 1.0 / 255 + 1e-9


# ---------------------------------------------------------------------------- thresholds
def test_a_red_range_wraps_through_zero_hue() -> None:
    rng = np.random.default_rng(1)
    hue = (rng.normal(0.0, 0.01, 500)) % 1.0
    hsv = np.stack([hue, rng.uniform(0.7, 0.9, 500), rng.uniform(0.5, 1.0, 500)], axis=1)
    r = fit_colour_range(hsv, rng.uniform(0, 255, (500, 3)))
    assert r.hsv_lo[0] > 0.9 and r.hsv_hi[0] < 0.1  # lo > hi: through 0


def test_colour_range_checks_its_values() -> None:
    with pytest.raises(ConfigError, match="hsv_lo must lie in"):
        ColourRange((1.5, 0.0, 0.0), (0.2, 1.0, 1.0))
    with pytest.raises(ConfigError, match="S range 0.9..0.1 is empty"):
        ColourRange((0.1, 0.9, 0.0), (0.2, 0.1, 1.0))


def test_learned_thresholds_separate_target_colours_from_the_distractors_on_held_out_images() -> None:
    plan = FitPlan(train_images=60, test_images=30, seed=5)
    ranges, record = fit(plan)
    assert set(ranges) <= set(PALETTE) and {"green", "red", "yellow"} <= set(ranges)
    for colour, spaces in record["held_out"].items():
        hsv = spaces["hsv"]
        assert hsv["true_positive"] is None or hsv["true_positive"] > 0.9, colour
        assert max(hsv["false_positive"].values()) < 0.02, (colour, hsv["false_positive"])
    # the exit sign is green too: HSV keeps it out of the target's green, a plain RGB box does not
    assert record["held_out"]["green"]["hsv"]["false_positive"]["exit sign"] < 0.02
    assert record["held_out"]["green"]["rgb"]["false_positive"]["exit sign"] > 0.1


def test_a_threshold_that_keeps_too_few_of_its_own_pixels_is_flagged_by_name_and_share(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import agents.papers.ceiling_target.fit as fitting
    from agents.cli import main

    def spaces(kept: float) -> dict:
        return {"hsv": {"true_positive": kept, "false_positive": {"ceiling": 0.0}}, "rgb": {"true_positive": kept}}

    record = {"plan": {"train_images": 20}, "training_pixels": {"red": 265, "blue": 92, "cyan": 2173},
              "held_out": {"red": spaces(0.997), "blue": spaces(0.333), "cyan": spaces(0.26)}}  # fmt: skip
    lines = fitting.fit_warnings(record)
    assert len(lines) == 2 and "blue keeps only 33 % of blue's own pixels" in lines[0] and "92 pixels of 20 training" in lines[0]
    assert "cyan keeps only 26 %" in lines[1] and "give more --train-images" in lines[1]
    # the command prints them, and the YAML's record keeps them
    monkeypatch.setattr(fitting, "fit", lambda plan: ({}, {**record, "warnings": lines}))
    assert main(["fit", "ceiling_target", "--out", str(tmp_path / "t.yaml"), "--train-images", "20"]) == 0
    err = capsys.readouterr().err
    assert f"warning: {lines[0]}" in err and f"warning: {lines[1]}" in err
    written = yaml.safe_load((tmp_path / "t.yaml").read_text().split(fitting.MARKER)[1])
    assert written["fitted_on"]["warnings"] == lines


def test_fit_options_have_help_and_are_checked(capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import main

    with pytest.raises(SystemExit):
        main(["fit", "ceiling_target", "--help"])
    shown = " ".join(capsys.readouterr().out.split())
    assert "--train-images TRAIN_IMAGES rendered, labelled images the thresholds are learned from (>= 10; default 160" in shown
    assert "--test-images TEST_IMAGES held-out images" in shown and "--seed SEED seed of the training images" in shown
    with pytest.raises(SystemExit):
        main(["fit", "ceiling_target", "--train-images", "5"])
    assert "argument --train-images: expected an integer >= 10, got 5" in capsys.readouterr().err


def test_the_shipped_thresholds_hold_on_fresh_images() -> None:
    params = load_params("ceiling_target")
    plan = FitPlan(test_images=30)
    images = list(labelled_images(plan, seed=12345, count=30))
    hsv = np.concatenate([hsv8(im).reshape(-1, 3) / [256.0, 255.0, 255.0] for im, _ in images])
    rgb = np.concatenate([im.reshape(-1, 3).astype(np.float64) for im, _ in images])
    lab = np.concatenate([labels.reshape(-1) for _, labels in images])
    assert params.fitted_on["plan"]["seed"] == 0  # the record of the data behind them is there
    for colour, rng in params.thresholds.items():
        hit = inside(rng, hsv, rgb, "hsv")
        mine = lab == colour_label(colour)
        if mine.sum() > 50:
            assert hit[mine].mean() > 0.9, colour
        assert hit[lab == LABEL_SIGN].mean() < 0.02, colour
        assert hit[~mine].mean() < 0.001, colour


# ---------------------------------------------------------------------------- round trip
def _sight(pose: np.ndarray, cam: CeilingCamera, intr: CameraIntrinsics, loc: CeilingTargetLocalizer) -> None:
    image, _ = cam.render(pose[None, :])
    loc.reset(np.random.default_rng(0), None)
    loc.update(CeilingImage(image, intr))


def _error(loc: CeilingTargetLocalizer, pose: np.ndarray) -> tuple[float, float]:
    d = loc.estimate.as_array() - pose
    return float(math.hypot(d[0], d[1])), abs(float((d[2] + math.pi) % (2 * math.pi) - math.pi))


def test_round_trip_on_clean_images_recovers_the_pose_and_the_target() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    footprint = intr.depth_m / intr.fx_px
    ceiling = env.config.features["ceiling"]
    assert isinstance(ceiling, CeilingConfig)
    rng = np.random.default_rng(2)
    errors = {"AB": [], "A": [], "B": []}
    for _ in range(240):
        target = ceiling.targets[rng.integers(len(ceiling.targets))]
        pose = np.array(
            [target.x_m + rng.uniform(-0.45, 0.45), target.y_m + rng.uniform(-0.35, 0.35), rng.uniform(-math.pi, math.pi)]
        )
        _sight(pose, cam, intr, loc)
        if loc.last_fix is None:
            continue
        assert loc.last_fix.name == target.name  # read from the colour code
        errors[loc.last_fix.ends].append(_error(loc, pose))
    both = np.array(errors["AB"])
    assert both.shape[0] > 80
    assert both[:, 0].max() <= footprint and both[:, 1].max() <= math.radians(1.0)
    one = np.array(errors["A"] + errors["B"])
    assert one.shape[0] > 40  # with one end and part of the line in view
    assert np.percentile(one[:, 0], 95) <= footprint and one[:, 0].max() <= 3 * footprint
    assert one[:, 1].max() <= math.radians(1.5)


def test_only_one_end_in_view_is_enough() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    footprint = intr.depth_m / intr.fx_px
    # 0.42 m to the side of a target: one end is out of view, the other and most of the line in;
    # T1's blue B and T2's magenta A are each the only end of their colour on a yellow line
    for x, y, end, name in ((0.42, 6.9, "B", "T1"), (-0.42, 13.9, "A", "T2")):
        pose = np.array([x, y, math.pi / 2])
        _sight(pose, cam, intr, loc)
        assert loc.last_fix is not None and loc.last_fix.ends == end and loc.last_fix.name == name
        position, heading = _error(loc, pose)
        assert position <= footprint and heading <= math.radians(1.0)


def test_ambiguous_readings_are_resolved_by_the_estimate_and_not_guessed_without_one() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    # only T0's and T1's green end A and part of their yellow line in view: both codes fit
    pose = np.array([-0.42, 6.9, math.pi / 2])
    image, _ = cam.render(pose[None, :])
    loc.reset(np.random.default_rng(0), None)
    loc.update(CeilingImage(image, intr))
    assert loc.last_fix is None and not loc.estimate.valid
    assert {r.name for r in loc.last_sightings[0]} == {"T0", "T1"}
    from localizers.base import PoseEstimate

    loc.reset(np.random.default_rng(0), PoseEstimate(-0.4, 6.8, math.pi / 2, np.diag([0.01, 0.01, 0.01])))
    loc.update(CeilingImage(image, intr))
    assert loc.last_fix is not None and loc.last_fix.name == "T1"


def test_fix_then_dead_reckoning_with_a_growing_covariance() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    _sight(np.array([0.0, 0.0, math.pi / 2]), cam, intr, loc)
    first = loc.estimate
    assert first.valid and first.position_spread_m < 0.05
    blank = np.zeros((intr.height_px, intr.width_px, 3), np.uint8)
    spreads = []
    for _ in range(40):
        loc.predict(OdometryDelta(0.025, 0.0, 0.0))
        loc.update(CeilingImage(blank, intr))
        spreads.append(loc.estimate.position_spread_m)
    assert all(b > a for a, b in zip(spreads, spreads[1:]))
    travelled = math.hypot(loc.estimate.x_m - first.x_m, loc.estimate.y_m - first.y_m)
    assert travelled == pytest.approx(1.0, abs=1e-9)  # 40 x 2.5 cm from the fix


def test_ekf_fusion_and_the_single_calibration_constant_run() -> None:
    env, cam, intr, _ = _setup()
    for params in ({"fusion": "ekf"}, {"metres_per_px": intr.depth_m / intr.fx_px}, {"undistort": True}, {"colour_space": "rgb"}):
        loc = make_localizer("ceiling_target", env.landmark_map, dt_s=0.05, params=params)
        pose = np.array([0.05, 6.95, 1.7])
        image, _ = cam.render(pose[None, :], None, 1.0, 7)
        from localizers.base import PoseEstimate

        loc.reset(np.random.default_rng(0), PoseEstimate(0.0, 6.9, 1.6, np.diag([0.01, 0.01, 0.01])))
        loc.update(CeilingImage(image, intr))
        position, heading = _error(loc, pose)
        assert loc.fixes == 1 and position < 0.03 and heading < 0.05, params


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "image", [np.zeros((240, 320, 3), np.float32), np.zeros((240, 320), np.uint8), np.zeros((120, 160, 3), np.uint8)]
)
def test_an_image_of_the_wrong_shape_or_dtype_is_refused(image: np.ndarray) -> None:
    _, _, intr, loc = _setup()
    loc.reset(np.random.default_rng(0))
    with pytest.raises(MeasurementError, match=r"expected a uint8 image of shape \(240, 320, 3\), got"):
        loc.update(CeilingImage(image, intr))


def test_a_target_colour_without_a_threshold_is_named() -> None:
    env = LocalizationEnv("ceiling_corridor")
    params = load_params("ceiling_target")
    thresholds = {k: v for k, v in params.thresholds.items() if k != "magenta"}
    with pytest.raises(ConfigError, match="no learned threshold for colour.* magenta"):
        make_localizer("ceiling_target", env.landmark_map, dt_s=0.05, params=dataclasses.replace(params, thresholds=thresholds))


def test_a_world_without_a_ceiling_is_refused() -> None:
    with pytest.raises(ConfigError, match="ceiling_target.*ceiling_camera sensor"):
        gym.make("crowdloc/CrowdedRoom-v0", localizer="ceiling_target")


def test_in_the_env_loop_it_is_deterministic_and_fixes_under_the_start_target() -> None:
    def run() -> list[np.ndarray]:
        env = gym.make("crowdloc/CeilingCorridor-v0", localizer="ceiling_target")
        obs, info = env.reset(seed=4)
        out = [info["estimate"].as_array()]
        for _ in range(30):
            obs, _, _, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
            out.append(info["estimate"].as_array())
        return out

    a, b = run(), run()
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert np.all(np.isfinite(a[0])) and abs(a[0][1]) < 0.03  # fixed on the first frame, under T0


# ---------------------------------------------------------------------------- lost and found
def _prior(x: float, y: float) -> PoseEstimate:
    return PoseEstimate(x, y, math.pi / 2, np.diag([1e-3, 1e-3, 1e-3]))


def test_after_a_kidnap_a_target_its_colours_fit_twice_makes_it_lost_and_the_next_one_fixes_it_by_colour() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    # carried from between T0 and T1 (the estimate) to beside T1: only a green end A and part of
    # a yellow line in view, which T0 and T1 both fit, each reading more than lost_offset_m away
    loc.reset(np.random.default_rng(0), _prior(-0.42, 3.5))
    image, _ = cam.render(np.array([-0.42, 6.9, math.pi / 2])[None, :])
    loc.update(CeilingImage(image, intr))
    assert {r.name for r in loc.last_sightings[0]} == {"T0", "T1"}
    assert loc.lost and not loc.estimate.valid and loc.last_fix is None  # the paper's rule took T1, the nearest
    # under T2 (magenta A, red B: no other target has these colours): a full fix, far from the dead reckoning
    truth = np.array([0.05, 13.95, 1.6])
    image, _ = cam.render(truth[None, :])
    loc.predict(OdometryDelta(0.5, 0.0, 0.0))
    loc.update(CeilingImage(image, intr))
    assert not loc.lost and loc.estimate.valid and loc.last_fix is not None and loc.last_fix.name == "T2"
    position, heading = _error(loc, truth)
    assert position < 0.03 and heading < 0.02


def test_an_unambiguous_target_far_from_the_estimate_replaces_it_even_with_ekf_fusion() -> None:
    env, cam, intr, _ = _setup(**CLEAN)
    loc = make_localizer("ceiling_target", env.landmark_map, dt_s=0.05, params={"fusion": "ekf"})
    loc.reset(np.random.default_rng(0), _prior(0.0, 3.0))
    truth = np.array([0.0, 20.8, math.pi / 2])  # under T3 (cyan line): 17.8 m from the estimate
    image, _ = cam.render(truth[None, :])
    loc.update(CeilingImage(image, intr))
    assert loc.estimate.valid and _error(loc, truth)[0] < 0.03  # fused, it would land half-way


def test_a_target_the_estimate_puts_in_view_unseen_for_lost_after_s_makes_it_lost() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    loc.reset(np.random.default_rng(0), _prior(0.0, 6.9))  # under T1 by the estimate
    blank, _ = cam.render(np.array([0.0, 10.0, math.pi / 2])[None, :])  # truth: tiles and a light, no target
    valid = []
    for _ in range(25):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
        loc.update(CeilingImage(blank, intr))
        valid.append(loc.estimate.valid)
    frames = round(load_params("ceiling_target").lost_after_s / 0.05)  # 1 s at 20 Hz
    assert all(valid[: frames - 1]) and not any(valid[frames - 1 :])
    # a target not predicted in view says nothing, nor does plain ceiling where the plan has no light
    # panel either (4.8 m off: two light pitches, the ceiling looks the same)
    loc.reset(np.random.default_rng(0), _prior(0.0, 5.2))
    for _ in range(25):
        loc.update(CeilingImage(blank, intr))
    assert loc.estimate.valid and not loc.lost


@pytest.mark.parametrize("name", ["lost_offset_m", "lost_after_s"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.nan])
def test_lost_detection_settings_are_checked(name: str, value: float) -> None:
    params = load_params("ceiling_target")
    with pytest.raises(ConfigError, match=f"ceiling_target.{name} must be > 0"):
        dataclasses.replace(params, **{name: value})


# ---------------------------------------------------------------------------- lost by the ceiling plan
def _drive(
    loc: CeilingTargetLocalizer,
    cam: CeilingCamera,
    intr: CameraIntrinsics,
    truth_y: np.ndarray,
    offset_m: float,
    heads_xy: np.ndarray | None = None,
) -> list[bool]:
    """Drive along the corridor's centre line at the truth's ``y`` (the default camera, its gain, noise
    and blur) from an estimate ``offset_m`` ahead of it; whether a pose was claimed after each frame."""
    cam.seed_noise(np.random.default_rng(1))
    loc.reset(np.random.default_rng(0), _prior(0.0, float(truth_y[0]) + offset_m))
    valid = []
    for k, y in enumerate(truth_y):
        pose = np.array([0.0, y, math.pi / 2])
        step = float(truth_y[k] - truth_y[k - 1]) if k else 0.0
        image, _ = cam.render(
            pose, gain=cam.gain(pose, 0.05 * k), noise_offset=997 * k, previous=pose - (0.0, step, 0.0), heads_xy=heads_xy
        )
        loc.predict(OdometryDelta(step, 0.0, 0.0))
        loc.update(CeilingImage(image, intr))
        valid.append(loc.estimate.valid)
    return valid


def test_between_targets_a_jump_shows_in_the_light_panels_and_makes_it_lost() -> None:
    env, cam, intr, loc = _setup()
    truth_y = np.arange(2.4, 4.4, 0.04)  # under the light panel at 3.6 m, no target in view
    assert all(_drive(loc, cam, intr, truth_y, 0.0))  # the estimate agrees with the panels: no false alarm
    assert loc.last_plan is None or loc.last_plan.unexplained_m2 == 0.0
    for jump in (0.9, -1.4, 3.0):  # the estimate 0.9 m ahead of the truth, 1.4 m behind it, 3 m ahead
        valid = _drive(loc, cam, intr, truth_y, jump)
        lost_at = valid.index(False) * 0.04
        assert loc.lost and not any(valid[valid.index(False) :]), jump
        assert lost_at < 1.5, (jump, lost_at)  # within 1.5 m of travel (3.75 s at the follower's 0.4 m/s)


def test_people_under_the_camera_hide_panels_without_contradicting_the_estimate() -> None:
    env, cam, intr, loc = _setup()
    truth_y = np.arange(2.6, 4.6, 0.02)
    heads = np.array([[0.0, 3.6], [0.1, 3.3], [-0.1, 3.9], [0.35, 3.0]])  # heads over the panel and beside it
    valid = _drive(loc, cam, intr, truth_y, 0.0, heads_xy=heads)
    assert all(valid) and not loc.lost
    # counted as plain ceiling, the hair would contradict the panel it hides (the test's reason for plan_min_value)
    loc = make_localizer(
        "ceiling_target", env.landmark_map, dt_s=0.05, params={"plan_min_value": 0.0, "plan_plain_saturation_max": 1.0}
    )
    assert isinstance(loc, CeilingTargetLocalizer)
    assert not all(_drive(loc, cam, intr, truth_y, 0.0, heads_xy=heads))


def test_a_jump_of_a_light_pitch_looks_the_same_and_the_next_target_tells_it_by_its_colours() -> None:
    env, cam, intr, _ = _setup()
    loc = make_localizer("ceiling_target", env.landmark_map, dt_s=0.05, params={"fusion": "ekf"})
    assert isinstance(loc, CeilingTargetLocalizer)
    pitch = env.config.features["ceiling"].light_pitch_m
    truth_y = np.arange(12.6, 13.4, 0.02)  # under the panel at 13.2 m, T2 (13.9 m) not yet in view
    assert all(_drive(loc, cam, intr, truth_y, -pitch))  # the panels cannot tell the estimate from the truth
    assert loc.last_plan is not None and loc.last_plan.matched_m2 > 0.01
    # T2 in view where the estimate puts nothing: its colours fix the pose, whatever the (EKF) estimate
    pose = np.array([0.0, 13.9, math.pi / 2])
    image, _ = cam.render(pose, gain=1.0)
    loc.update(CeilingImage(image, intr))
    assert loc.estimate.valid and loc.last_fix is not None and loc.last_fix.name == "T2" and _error(loc, pose)[0] < 0.05


def test_a_fix_after_the_plan_made_it_lost_replaces_the_pose_with_ekf_fusion() -> None:
    env, cam, intr, _ = _setup()
    loc = make_localizer("ceiling_target", env.landmark_map, dt_s=0.05, params={"fusion": "ekf"})
    assert isinstance(loc, CeilingTargetLocalizer)
    assert not all(_drive(loc, cam, intr, np.arange(12.4, 13.4, 0.02), -1.0)) and loc.lost
    pose = np.array([0.05, 13.9, math.pi / 2])
    image, _ = cam.render(pose, gain=1.0)
    loc.update(CeilingImage(image, intr))
    assert loc.estimate.valid and _error(loc, pose)[0] < 0.05  # fused with the wrong pose, it would land 0.5 m off


def test_the_ceiling_plan_matches_the_rendered_light_panels_and_signs() -> None:
    env, cam, intr, loc = _setup(**CLEAN)
    plan = CeilingPlan.from_map_data(env.landmark_map.features["ceiling"])
    assert plan is not None
    points = cell_points(intr, 4)
    for pose in ([0.0, 3.5, math.pi / 2], [0.4, 6.2, 1.3], [-0.3, 14.3, 2.0]):
        _, labels = cam.render(np.array(pose), labels=True)
        assert labels is not None
        c, s = math.cos(pose[2]), math.sin(pose[2])
        xy = np.stack([pose[0] + c * points[:, 0] - s * points[:, 1], pose[1] + s * points[:, 0] + c * points[:, 1]], axis=1)
        label = labels[2::4, 2::4].ravel()
        distance = plan.white_distance(xy)
        white = (label == LABEL_LIGHT) | ((label == LABEL_SIGN) & (distance <= 0.01))
        assert np.all(distance[label == LABEL_LIGHT] <= 0.01)  # every panel pixel lies in the plan's white
        assert np.all(white[distance < -0.01])  # and the plan's white shows white (a panel or a sign's lettering)


def test_plan_settings_are_checked() -> None:
    params = load_params("ceiling_target")
    with pytest.raises(ConfigError, match="plan_white_saturation < plan_plain_saturation"):
        dataclasses.replace(params, plan_white_saturation=0.05)
    with pytest.raises(ConfigError, match="ceiling_target.plan_after_s must be > 0"):
        dataclasses.replace(params, plan_after_s=math.nan)
    with pytest.raises(ConfigError, match="plan_cell_px must be in 1..16"):
        dataclasses.replace(params, plan_cell_px=0)


def test_the_fit_renders_its_images_under_the_cameras_light() -> None:
    """``crowdloc fit ceiling_target --camera``: the same poses and labels, each channel scaled by the light's colour."""
    warm = FitPlan(camera={**IDEAL, "white_balance_k": 6500.0, "cct_k": [4000.0, 4000.0]})
    plain = FitPlan(camera=dict(IDEAL))
    cam = LocalizationEnv("ceiling_corridor", camera=warm.camera).sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    colour = cam.channel_gains(np.zeros(3), 0.0) / cam.gain(np.zeros(3), 0.0)
    for (image, labels), (tinted, tinted_labels) in zip(labelled_images(plain, 3, 4), labelled_images(warm, 3, 4)):
        assert np.array_equal(labels, tinted_labels)
        for c in (0, 2):
            want = image[..., c].astype(np.float64) * colour[c]
            unclipped = (want < 250) & (image[..., c] < 255)
            assert unclipped.sum() > 100
            assert np.abs(tinted[..., c][unclipped] - want[unclipped]).max() <= 0.5 + 0.5 * colour[c] + 1e-6  # two roundings
    with pytest.raises(argparse.ArgumentTypeError, match=r"--camera must be a JSON mapping of the camera's fields, got '\[1\]'"):
        camera_json("[1]")
