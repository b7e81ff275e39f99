"""A synthetic campus map (walls only) for the campus-scale tests of the LIDAR localizer."""

from __future__ import annotations

import math

import numpy as np


def campus_walls(rng: np.random.Generator, count: int = 1000, size_m: tuple[float, float] = (150.0, 100.0)) -> np.ndarray:
    """``(count, 4)`` walls of a synthetic campus: the boundary, buildings (turned rectangles of
    sides 5-40 m) and poles and trees (polygons of 4-8 sides of 0.1 m), overlapping at random."""
    w, h = size_m
    walls = [[0.0, 0.0, w, 0.0], [w, 0.0, w, h], [w, h, 0.0, h], [0.0, h, 0.0, 0.0]]
    while len(walls) < count:
        centre = rng.uniform((0.0, 0.0), (w, h))
        if rng.random() < 0.3:
            half = rng.uniform(5.0, 40.0, 2) / 2
            turn = rng.uniform(0.0, math.pi)
            c, s = math.cos(turn), math.sin(turn)
            corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half @ np.array([[c, s], [-s, c]]) + centre
        else:
            sides = int(rng.integers(4, 9))
            radius = 0.05 / math.sin(math.pi / sides)
            a = rng.uniform(0.0, 2 * math.pi) + 2 * math.pi * np.arange(sides) / sides
            corners = centre + radius * np.column_stack([np.cos(a), np.sin(a)])
        walls += [[*p, *q] for p, q in zip(corners, np.roll(corners, -1, axis=0))]
    return np.asarray(walls[:count], dtype=np.float64)
