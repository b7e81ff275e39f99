"""The stereo campus's free-running webcams: edges per row in the image mode against the fast
mode on the same scenes, and the fast mode's step rate with and without the options.

1. Agreement: per seed and crowd size, the campus is driven (fast mode; the webcam options on or off, the fast
   mode's ``fast_edges`` lines or rows) along
   the route's first leg with a wandering turn; every ``--every`` steps the same state is observed by an
   image-mode camera sharing the fast camera's draws (frame lags, gains per camera, the exposure drift). Per
   camera and detection row: the edges each mode finds, their types (channel x polarity), and the matched
   detections (slots filled of 96). Both modes keep their own noise (pixel noise 2, edge noise 0.4 px).
2. Cost: the campus's step rate in the fast mode (crowd 30, and 100 pedestrians + 10 cars), best and median
   of repeats, without and with the options (the webcams and ``fast_edges: rows``).

Run: ``.venv/bin/python -m benchmarks.stereo_webcams [--seeds 3] [--steps 120] [--every 20] [--rate-steps 600]
[--repeats 3] [--skip-agreement] [--skip-cost]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the ids)
from envs.sensors.stereo_camera import StereoCamera
from envs.stereo.vision import LEVELS, edge_types_parts, match_checked

ENV_ID = "crowdloc/StereoCampus-v0"
#: the options at the values their fields cite (envs/sensors/stereo_camera.py)
WEBCAMS = {"synchronised": False, "exposure_range": (0.51, 1.49), "white_balance_k": (5003.0, 7504.0)}
ROWS = {"fast_edges": "rows"}
BUSY = {"crowd_size": 110, "crowd": {"campus": {"car_share": 10 / 110}}}


def _actions(steps: int, seed: int) -> np.ndarray:
    """Forward at 0.5-1 of full speed with a wandering turn (as benchmarks.bench_stereo drives)."""
    rng = np.random.default_rng(seed)
    actions = np.empty((steps, 2), dtype=np.float32)
    actions[:, 0] = rng.uniform(0.5, 1.0, steps)
    actions[:, 1] = np.clip(np.cumsum(rng.normal(0.0, 0.1, steps)), -0.6, 0.6)
    return actions


def _image_twin(fast: StereoCamera, env: Any) -> StereoCamera:
    """An image-mode camera on the same world, to be given the fast camera's draws before each frame."""
    base = env.unwrapped
    config = dataclasses.replace(fast.config, mode="image", gain_std=0.0)
    return StereoCamera("stereo", config, base.config, base.state)


def _counts(edges: Any) -> np.ndarray:
    """``(LEVELS, 6)`` edges per detection row and (channel, polarity)."""
    out = np.zeros((LEVELS, 6))
    channel, level, falling = edge_types_parts(edges.type)
    np.add.at(out, (level, 2 * channel + falling.astype(np.int64)), 1)
    return out


def agreement(seeds: int, steps: int, every: int, crowds: tuple[int, ...], stereo: dict[str, Any], label: str) -> None:
    print(f"## edges per camera and detection row, image mode vs fast mode ({label})")
    print("crowd | frames | edges per row, image (rows 0-4) | fast | fast / image per row | types: max |fast/image - 1| "
          "| matched, image | fast")  # fmt: skip
    for crowd in crowds:
        per_image: list[Any] = []
        per_fast: list[Any] = []
        matched_image: list[int] = []
        matched_fast: list[int] = []
        for seed in range(seeds):
            env = gym.make(ENV_ID, crowd_size=crowd, stereo=stereo)
            env.reset(seed=seed)
            base: Any = env.unwrapped
            fast = base.sensors["stereo"]
            assert isinstance(fast, StereoCamera)
            image = _image_twin(fast, env)
            rng = np.random.default_rng(seed)
            image.observe(base.state, rng)  # its noise pool
            for k, a in enumerate(_actions(steps, seed)):
                env.step(a)
                if k % every:
                    continue
                image.frame_lags_s, image.camera_gains, image._gain = fast.frame_lags_s, fast.camera_gains, fast._gain
                image.observe(base.state, rng)
                c = fast.config
                for cam, counts, matched in ((image, per_image, matched_image), (fast, per_fast, matched_fast)):
                    counts.append(sum(_counts(e) for e in cam.last_edges) / 3.0)
                    left, middle, right = cam.last_edges
                    found = match_checked(left, middle, right, *cam._window, c.match_tolerance_px)
                    matched.append(min(found.type.size, c.slots))
            env.close()
        img, fst = np.mean(per_image, axis=0), np.mean(per_fast, axis=0)
        rows_i, rows_f = img.sum(axis=1), fst.sum(axis=1)
        types_i, types_f = img.sum(axis=0), fst.sum(axis=0)
        ratio = " ".join(f"{f / i:.2f}" if i else "-" for f, i in zip(rows_f, rows_i))
        type_gap = float(np.max(np.abs(types_f / np.maximum(types_i, 1e-9) - 1.0)))
        print(
            f"{crowd} | {len(per_image)} | {' '.join(f'{v:.1f}' for v in rows_i)} | {' '.join(f'{v:.1f}' for v in rows_f)} | "
            f"{ratio} | {type_gap:.2f} | {np.mean(matched_image):.1f} | {np.mean(matched_fast):.1f}"
        )


def step_rate(steps: int, repeats: int, **kwargs: Any) -> tuple[float, float]:
    """Best and median steps/s of the fast-mode campus driven by :func:`_actions`."""
    env = gym.make(ENV_ID, **kwargs)
    env.reset(seed=0)
    actions = _actions(steps, 0)
    env.step(actions[0])  # compile outside the timing
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        rates.append(steps / (time.perf_counter() - start))
    env.close()
    return float(np.max(rates)), float(np.median(rates))


def observe_ms(rounds: int, **kwargs: Any) -> list[float]:
    """Per round, the mean time of one fast-mode observation of the stereo camera (ms) over 200 states of the
    drive (the same states every round)."""
    env = gym.make(ENV_ID, **kwargs)
    env.reset(seed=0)
    base: Any = env.unwrapped
    states = []
    for a in _actions(200, 0):
        env.step(a)
        states.append(base.state)
    camera, rng = base.sensors["stereo"], np.random.default_rng(0)
    camera.observe(states[0], rng)  # compile
    out = []
    for _ in range(rounds):
        start = time.perf_counter()
        for state in states:
            camera.observe(state, rng)
        out.append((time.perf_counter() - start) / len(states) * 1e3)
    env.close()
    return out


def cost(steps: int, repeats: int) -> None:
    print("## the stereo camera's fast-mode observation, 100 pedestrians + 10 cars (mean ms over 200 states; off / on)")
    for _ in range(3):  # interleaved, so that the host's swings hit both alike
        off, on = observe_ms(3, **BUSY), observe_ms(3, **BUSY, stereo={**WEBCAMS, **ROWS})
        print(f"best {min(off):.3f} / {min(on):.3f}, median {np.median(off):.3f} / {np.median(on):.3f}")
    print("## the campus's step rate, fast mode (best / median of repeats, steps/s)")
    for name, extra in (("crowd 30", {}), ("100 pedestrians + 10 cars", BUSY)):
        # interleaved, so that the host's swings hit both alike
        off, on = [], []
        for _ in range(2):
            off.append(step_rate(steps, repeats, **extra))
            on.append(step_rate(steps, repeats, **extra, stereo={**WEBCAMS, **ROWS}))
        best_off, best_on = max(r[0] for r in off), max(r[0] for r in on)
        med_off, med_on = np.median([r[1] for r in off]), np.median([r[1] for r in on])
        print(f"{name}: off {best_off:,.0f} / {med_off:,.0f}, on {best_on:,.0f} / {med_on:,.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=120)
    parser.add_argument("--every", type=int, default=20)
    parser.add_argument("--rate-steps", type=int, default=600)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-cost", action="store_true")
    parser.add_argument("--skip-agreement", action="store_true")
    args = parser.parse_args()
    lags = {"synchronised": False, **ROWS}
    gains = {"exposure_range": WEBCAMS["exposure_range"], "white_balance_k": WEBCAMS["white_balance_k"], **ROWS}
    configs: tuple[tuple[dict[str, Any], str], ...] = (
        ({}, "today's cameras, fast_edges lines"),
        (ROWS, "today's cameras, fast_edges rows"),
        (WEBCAMS, "webcams on, fast_edges lines"),
        ({**WEBCAMS, **ROWS}, "webcams on, fast_edges rows"),
        (lags, "frame lags only, fast_edges rows"),
        (gains, "exposure and white balance only, fast_edges rows"),
    )
    for stereo, label in () if args.skip_agreement else configs:
        agreement(args.seeds, args.steps, args.every, (0, 30), stereo, label)
    if not args.skip_cost:
        cost(args.rate_steps, args.repeats)


if __name__ == "__main__":
    main()
