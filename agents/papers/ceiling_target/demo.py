"""The corridor section of ``make demo``: one drive among people, one camera frame with what the
pipeline found drawn on it, and one top view."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from agents.policies import make_policy
from envs.localization_env import LocalizationEnv
from envs.render import Renderer
from localizers.ceiling_target import CeilingImage, CeilingTargetLocalizer
from localizers.ceiling_target.vision import CameraIntrinsics, Sighting
from localizers.registry import make_localizer

from . import paper
from .drive import ENV_ID, DriveTask, drive, summarize
from .fit import camera_of

DEMO_CROWD = 10


def annotate(image: NDArray[np.uint8], sightings: list[list[Sighting]]) -> NDArray[np.uint8]:
    """A copy of ``image``, 3 times larger, with each reading's fitted line (white), end A (green
    ring) and end B (red ring) drawn on it."""
    scale = 3
    out = np.ascontiguousarray(cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST), dtype=np.uint8)
    for readings in sightings:
        r = readings[0]
        (u0, v0), (u1, v1) = r.line_ends_px
        cv2.line(out, (int(u0 * scale), int(v0 * scale)), (int(u1 * scale), int(v1 * scale)), (255, 255, 255), 1, cv2.LINE_AA)
        for centre, colour in ((r.a_px, (0, 255, 0)), (r.b_px, (255, 0, 0))):
            if all(math.isfinite(c) for c in centre):
                cv2.circle(out, (int(centre[0] * scale), int(centre[1] * scale)), 5 * scale, colour, 2, cv2.LINE_AA)
        label = f"{r.name}: ends {r.ends}"
        cv2.putText(out, label, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2, cv2.LINE_AA)
    return out


def camera_frame(path: Path) -> Sighting | None:
    """The camera's image under target T1, 8 cm off and turned by 20 deg, with a person pressing
    on the robot at the image corner; what the pipeline read, drawn on it (saved to ``path``)."""
    env = LocalizationEnv("ceiling_corridor")
    camera = camera_of(env)
    rng = np.random.default_rng(0)
    camera.seed_noise(rng)
    target = camera.ceiling.targets[1]
    pose = np.array([target.x_m + 0.08, target.y_m - 0.05, math.pi / 2 + math.radians(20)])
    corner = math.atan2(0.55 * 0.95 / 1.75, 0.42 * 0.95 / 1.75)
    head = pose[:2] + 0.476 * np.array([math.cos(pose[2] + corner), math.sin(pose[2] + corner)])
    image, _ = camera.render(pose, head[None, :], 1.0, 12345)
    localizer = make_localizer("ceiling_target", env.landmark_map, dt_s=env.config.dt_s)
    assert isinstance(localizer, CeilingTargetLocalizer)
    localizer.reset(rng, None)
    localizer.update(CeilingImage(image, CameraIntrinsics.from_metadata(camera.metadata())))
    cv2.imwrite(str(path), cv2.cvtColor(annotate(image, localizer.last_sightings), cv2.COLOR_RGB2BGR))
    return localizer.last_fix


def top_view(path: Path, seed: int = 0) -> None:
    """A top-view frame of the corridor around the robot as it reaches target T1 among people."""
    env = gym.make(ENV_ID, crowd_size=DEMO_CROWD, localizer="ceiling_target", render_mode="rgb_array")
    policy = make_policy("corridor_follower", env, seed=seed)
    obs, info = env.reset(seed=seed)
    y_goal = paper.DRIVE_TARGETS_M[0]
    for _ in range(env.spec.max_episode_steps if env.spec and env.spec.max_episode_steps else 3000):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        if info["true_pose"][1] >= y_goal - 0.01 or terminated or truncated:
            break
    frame = np.asarray(env.render())
    # the frame follows the robot through 12 m of the corridor (its view_m): keep the corridor's width
    # and the 8 m around the robot, located by a renderer of the same world looking where the frame's did
    base = env.unwrapped
    assert isinstance(base, LocalizationEnv)
    renderer = Renderer(base.config, "rgb_array", 30)
    x, y = (float(v) for v in info["true_pose"][:2])
    renderer.look_at((x, y))
    xmin, _, xmax, _ = base.config.arena_m
    (left, top), (right, bottom) = renderer.to_pixel([[xmin, y + 4.0], [xmax, y - 4.0]])
    crop = frame[max(0, top) : bottom, max(0, left - 8) : right + 8]
    crop = cv2.resize(np.ascontiguousarray(crop), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(path), cv2.cvtColor(crop, cv2.COLOR_RGB2BGR))
    env.close()


def corridor_section(out_dir: Path, seed: int = 0) -> str:
    """Run the drive, save the two frames; the report section as markdown."""
    out_dir.mkdir(parents=True, exist_ok=True)
    result = drive(DriveTask(seed, DEMO_CROWD))
    fix = camera_frame(out_dir / "ceiling_camera.png")
    top_view(out_dir / "corridor_top.png", seed)
    summary = summarize([result], paper.DRIVE_TARGETS_M)
    lines = [
        f"## The ceiling corridor (`{ENV_ID}`, {DEMO_CROWD} people, seed {seed})",
        "",
        f"The corridor_follower on `ceiling_target` drove the 20.8 m route in {result.time_s:.0f} s "
        f"({'reached' if result.reached_goal else 'did not reach'} the goal), with {result.fixes} fixes, "
        f"{result.remeasures} re-measurements, {result.missed} missed targets and {result.contacts} contact events.",
        "",
        "| target | true error at the stop (X, Y) [cm] | paper, Table 6 (empty corridor) |",
        "|:---|---:|---:|",
    ]
    for y in paper.DRIVE_TARGETS_M:
        s = summary[y]
        lines.append(f"| {y:g} m | ({s['x_mean']:.1f}, {s['y_mean']:.1f}) | {paper.TABLE6_CM[y]} |")
    found = "nothing" if fix is None else f"{fix.name} (ends {fix.ends})"
    lines += [
        "",
        f"The camera under T1, 8 cm off, turned 20 deg, a person's head in the corner; the pipeline read {found} "
        "(fitted line in white, end A ringed green, B red):",
        "",
        "![ceiling camera](corridor/ceiling_camera.png)",
        "",
        "The top view as the robot reaches T1:",
        "",
        "![corridor top view](corridor/corridor_top.png)",
        "",
        "`crowdloc reproduce ceiling-target` re-runs the paper's Tables 2-6 and the studies beyond it.",
        "",
    ]
    return "\n".join(lines)
