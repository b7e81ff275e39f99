"""Open-loop paths: a polygon driven as straight legs and turns in place, as ``[-1, 1]`` actions.

Pure geometry on the robot's limits, with no world in sight: the fixed policy ``patrol``
(:meth:`agents.policies.PatrolPath.exp1`) and the scripted drivers of the reproductions
(:class:`agents.experiments.scenarios.OpenLoopDriver`) both play these commands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.geometry import wrap_angle

#: Exp 1 path (ours): the paper's Fig. 11 is not in the OCR text. A convex octagon in the
#: 5 m x 10 m field starting at a = (2.5, 8) facing +x (the world's start pose), clockwise.
#: L5 (corner pole at (5, 10), visible up to 4.6 m) is in range on h-a-b-c-d (a: 3.2 m,
#: d: 4.36 m) and out of range on d-e-f-g-h (h: 5.24 m), as the paper reports.
EXP1_VERTICES: dict[str, tuple[float, float]] = {
    "a": (2.5, 8.0),
    "b": (3.8, 8.0),
    "c": (4.3, 7.0),
    "d": (4.3, 5.7),
    "e": (3.5, 2.5),
    "f": (1.5, 2.5),
    "g": (0.7, 4.0),
    "h": (0.7, 7.0),
}


@dataclass(frozen=True)
class Command:
    """Drive at ``v_mps`` and turn at ``omega_rps`` for ``steps`` steps."""

    v_mps: float
    omega_rps: float
    steps: int


def polygon_commands(
    vertices: Sequence[tuple[float, float]],
    start_heading_rad: float,
    *,
    speed_mps: float,
    turn_rate_rps: float,
    dt_s: float,
    close: bool = True,
) -> list[Command]:
    """Open-loop commands for a polygon: turn in place at each vertex, then drive straight.

    Each leg's speed (and each turn's rate) is lowered slightly from the nominal value so
    that it lasts a whole number of steps and ends exactly on the vertex (heading).

    Args:
        vertices: ``(x, y)`` corners in driving order; the robot starts on the first.
        start_heading_rad: the robot's heading at the first vertex.
        speed_mps: nominal straight-line speed.
        turn_rate_rps: nominal turn rate in place.
        dt_s: the env's time step.
        close: drive back to the first vertex and turn to ``start_heading_rad``.

    Returns:
        Commands in order (turns of zero angle are omitted).
    """
    if speed_mps <= 0 or turn_rate_rps <= 0 or dt_s <= 0:
        raise ValueError(f"polygon_commands: speed, turn rate and dt must be > 0, got {speed_mps}, {turn_rate_rps}, {dt_s}")
    points = [np.asarray(v, dtype=np.float64) for v in vertices]
    if close:
        points.append(points[0])
    commands: list[Command] = []
    heading = float(start_heading_rad)

    def turn_to(target: float) -> None:
        angle = float(wrap_angle(target - heading))
        if abs(angle) < 1e-12:
            return
        steps = math.ceil(abs(angle) / (turn_rate_rps * dt_s))
        commands.append(Command(0.0, angle / (steps * dt_s), steps))

    for p, q in zip(points[:-1], points[1:]):
        d = q - p
        length = float(np.hypot(*d))
        if length < 1e-12:
            continue
        target = math.atan2(d[1], d[0])
        turn_to(target)
        heading = target
        steps = math.ceil(length / (speed_mps * dt_s))
        commands.append(Command(length / (steps * dt_s), 0.0, steps))
    if close:
        turn_to(float(start_heading_rad))
    return commands


def command_actions(commands: Sequence[Command], max_speed_mps: float, max_turn_rate_rps: float) -> NDArray[np.float32]:
    """``(steps, 2)`` actions in ``[-1, 1]`` that play ``commands`` on a robot with these limits.

    Raises:
        ValueError: naming a command beyond the robot's limits.
    """
    rows = []
    for c in commands:
        a = np.array([c.v_mps / max_speed_mps, c.omega_rps / max_turn_rate_rps], dtype=np.float32)
        if not np.all(np.abs(a) <= 1.0):
            raise ValueError(f"command {c} exceeds the robot's limits ({max_speed_mps} m/s, {max_turn_rate_rps} rad/s)")
        rows.append(np.tile(a, (c.steps, 1)))
    return np.concatenate(rows) if rows else np.zeros((0, 2), dtype=np.float32)


def square_vertices(center_xy: tuple[float, float], side_m: float) -> list[tuple[float, float]]:
    """Corners of an axis-aligned square, counter-clockwise from the lower-left one."""
    if not side_m > 0:
        raise ValueError(f"square_vertices: side_m must be > 0, got {side_m!r}")
    cx, cy = center_xy
    h = side_m / 2.0
    return [(cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h)]
