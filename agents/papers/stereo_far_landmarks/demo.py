"""The campus section of ``make demo``: a short drive of ``route_follower`` on ``far_landmark_pf``'s
estimate among the campus crowd, one camera image with its edges marked by type, and one top view
with the particles and the far landmarks the last update selected.

The filter's own overlay draws its particles and the selected far landmarks as dots
(``FarLandmarkPF.overlay``), but the landmarks it selects are far (tens of metres, the farthest
matching detection per 30 deg sector) and mostly lie beyond the top view's 40 m x 30 m window;
the section adds, through the env's overlay hook (``env.add_overlay``), a sight line from the
estimate to each, so their directions show in the window.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from agents.policies import make_policy
from envs.localization_env import LocalizationEnv
from envs.sensors.stereo_camera import StereoCamera
from localizers.far_landmark_pf import FarLandmarkPF

from .experiment import ENV_ID

#: the stretch driven (s of simulated time): the first ~25 m of the route, west along the north sidewalk
DEMO_SECONDS = 30.0
LOCALIZER = "far_landmark_pf"
#: the sight lines to the selected far landmarks (the sensor's rays are red, green and blue, the estimate magenta)
SELECTED_COLOR = (255, 220, 0)


def sight_lines(localizer: FarLandmarkPF) -> Callable[[Any], None]:
    """An overlay (``env.add_overlay``) drawing a line from the filter's estimate to each far landmark its
    last update selected (``used_xy``), ringed where it lies inside the window (the filter's own overlay
    already counts them in the caption)."""

    def draw(canvas: Any) -> None:
        est = localizer.estimate
        if not np.isfinite(est.as_array()).all():
            return
        for x, y in localizer.used_xy:
            canvas.line((est.x_m, est.y_m), (x, y), SELECTED_COLOR, 3)
            canvas.circle(x, y, 1.0, SELECTED_COLOR, 2)

    return draw


def _write_png(path: Path, image: NDArray[np.uint8]) -> None:
    if not cv2.imwrite(str(path), cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {path}")


def campus_section(out_dir: Path, seed: int = 0, seconds: float = DEMO_SECONDS, scene_map: Path | None = None) -> str:
    """Drive ``seconds`` of the campus route on the far-landmark filter's estimate; save the middle
    camera's image with its edges marked (``campus_camera.png``) and the top view at the end of the
    stretch (``campus_top.png``) in ``out_dir``; the report section as markdown.

    Args:
        scene_map: the filter's map of scenes (None: the world's default, built and cached on first use).
    """
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"campus_section: seconds must be finite and > 0, got {seconds!r}")
    out_dir.mkdir(parents=True, exist_ok=True)
    params: dict[str, Any] = {} if scene_map is None else {"localizer_params": {"scene_map": str(scene_map)}}
    start = time.perf_counter()
    env = gym.make(ENV_ID, localizer=LOCALIZER, render_mode="rgb_array", **params)
    made_s = time.perf_counter() - start
    base = env.unwrapped
    assert isinstance(base, LocalizationEnv)
    localizer = env.get_wrapper_attr("localizer")
    assert isinstance(localizer, FarLandmarkPF)
    base.add_overlay(sight_lines(localizer))
    camera_name = next(name for name, sensor in base.sensors.items() if isinstance(sensor, StereoCamera))
    camera = base.sensors[camera_name]
    assert isinstance(camera, StereoCamera)
    crowd = base.config.crowd.count if base.config.crowd is not None else 0  # what crowd_size sets (parked cars aside)
    policy = make_policy("route_follower", env, seed=seed)
    obs, info = env.reset(seed=seed)
    start_xy = np.asarray(info["true_pose"][:2], dtype=np.float64)
    steps = max(1, round(seconds / base.config.dt_s))
    errors: list[float] = []
    detections: list[int] = []
    found: list[int] = []
    used: list[int] = []
    used_range: list[float] = []
    drive_start = time.perf_counter()
    for _ in range(steps):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        est = info["estimate"]
        truth = np.asarray(info["true_pose"], dtype=np.float64)
        errors.append(math.hypot(est.x_m - truth[0], est.y_m - truth[1]) if est.valid else math.nan)
        detections.append(int(info[f"{camera.key}_detections"]))
        found.append(detections[-1] + int(info[f"{camera.key}_dropped"]))
        used.append(len(localizer.used_xy))
        used_range.extend(np.hypot(*(localizer.used_xy - truth[:2]).T))
        if terminated or truncated:
            break
    drive_s = time.perf_counter() - drive_start
    # the frame: the middle camera's image with the edges it found, each marked by type (StereoCamera.views)
    width = camera.config.width_px
    strip = camera.views(base.world.snapshot())
    _write_png(out_dir / "campus_camera.png", strip[:, width : 2 * width])
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    _write_png(out_dir / "campus_top.png", frame)
    env.close()

    err = np.asarray(errors)
    valid = np.isfinite(err)
    sim_s = len(errors) * base.config.dt_s
    travelled = float(np.hypot(*(np.asarray(info["true_pose"][:2], dtype=np.float64) - start_xy)))
    error_text = (
        f"mean {err[valid].mean():.2f} m, max {err[valid].max():.2f} m over the {int(valid.sum())} of {len(errors)} "
        "steps with a pose"
        if valid.any()
        else f"no pose in any of the {len(errors)} steps"
    )
    last = info["estimate"]
    spread = math.sqrt(max(0.0, float(np.trace(np.asarray(last.covariance)[:2, :2])))) if last.valid else math.nan
    far = np.asarray(used_range)
    far_text = f", {np.median(far):.0f} m from the robot (median; nearest {far.min():.0f} m)" if far.size else ""
    made_note = " (the default map is built and cached on first use)" if scene_map is None else ""
    map_text = "the world's default scene map" if scene_map is None else f"the scene map {scene_map.name}"
    lines = [
        f"## The stereo campus (`{ENV_ID}`, crowd {crowd}, seed {seed})",
        "",
        f"`route_follower` drove {sim_s:.0f} s of the route ({travelled:.1f} m from the start) on `{LOCALIZER}`'s "
        f"estimate ({map_text}). Position error against the truth: {error_text}. Per step the stereo camera matched "
        f"{np.mean(found):.0f} edges on average ({np.mean(detections):.0f} reported, at most {camera.config.slots} slots; "
        f"at the last step {found[-1]} and {detections[-1]}), and the filter selected {np.mean(used):.1f} far landmarks "
        f"(at the last step {used[-1]}){far_text}. At the last step the particles' position spread is "
        f"{100 * spread:.0f} cm (a few pixels at the top view's scale, under the estimate's mark). Wall time: {made_s:.1f} s to make the env{made_note}, {drive_s:.1f} s to drive.",
        "",
        "The middle camera's image at the last step, its edges marked by type (a marker in the channel's colour on "
        "its detection row, hollow for a rising edge, filled for a falling one):",
        "",
        f"![campus camera]({out_dir.name}/campus_camera.png)",
        "",
        "The top view at the same step (a 40 m x 30 m window that follows the robot): the filter's particles and "
        "estimate (magenta), the camera's rays to its detections (in their channels' colours), a yellow sight line "
        "from the estimate to each far landmark the last update selected (ringed where it lies inside the window); "
        "under it the three cameras' images:",
        "",
        f"![campus top view]({out_dir.name}/campus_top.png)",
        "",
        "`crowdloc reproduce stereo-far-landmarks` re-runs the paper's experiment (runs 1 and 2, crowd sizes 0-150).",
        "",
    ]
    return "\n".join(lines)
