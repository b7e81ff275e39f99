"""The localizer's belief as a fixed-size image a policy can read: ``belief_map``.

A point estimate and a spread cannot show a policy the belief's shape: two clusters of particles
a room's width apart (a symmetric room's twin) and one wide cloud give the same spread. The belief
map keeps the shape: a ``(heading_bins, cells, cells)`` float32 histogram of the localizer's own
hypotheses (its particles or candidates with their weights, :meth:`Localizer.overlay`), normalised
to sum to 1 (all zeros while the localizer holds no hypothesis).

- **Frame** (``frame``). ``estimate`` (the default): a square window of side ``extent_m`` centred
  on the localizer's estimate and turned so that its +x axis is the estimate's heading; headings are
  relative to the estimate's. It is egocentric because the policy acts in the robot's frame and
  what it can act on is the belief's shape around where it believes it is (a twin two metres to
  its left, a cloud stretched along the corridor): the same picture in every layout and in worlds
  of any size (the campus's 150 m at 32 cells would be 4.7 m cells in the world frame). A hypothesis
  outside the window counts in the border cell nearest to it, so far-away mass stays visible. While
  the estimate is not valid the window is centred on the hypotheses' weighted mean position and
  circular mean heading. ``world``: the world's bounds, headings in the world frame, for layouts
  that do not change.
- **Heading channels.** ``heading_bins`` equal bins over ``[-pi, pi)``, the first starting at -pi
  (relative headings in the estimate frame, so the estimate's own heading falls in the middle of
  the bin that holds 0 when ``heading_bins`` is odd and on a boundary when even).
- **A Gaussian belief.** A localizer whose overlay holds one pose with a finite covariance
  (``kalman``, ``dead_reckoning``; ``resection``'s overlay holds its triples' poses) is rendered
  the same way: the density of its position Gaussian at the cell centres times the probability of
  each heading bin under its heading's normal distribution (wrapped over one turn each side),
  normalised. One pose without a finite covariance is one cell.

Nothing here reads the truth: the map is a function of the overlay, the estimate and the world's
bounds (``tests/agents/test_belief_map.py`` moves the robot and checks the map does not change).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from core.types import Overlay, PoseEstimate

FRAMES = ("estimate", "world")


@dataclass(frozen=True)
class BeliefMapConfig:
    """The ``observation.belief_map`` section of a training config (module docstring)."""

    cells: int = 0  # > 0: add belief_map, a cells x cells grid per heading channel; 0: none
    heading_bins: int = 4  # heading channels over [-pi, pi)
    frame: str = "estimate"  # "estimate": centred on the estimate and turned to its heading; "world": the world's bounds
    extent_m: float = 4.0  # the side of the estimate-frame window (unused in the world frame)

    def __post_init__(self) -> None:
        check(0 <= self.cells <= 256, f"observation.belief_map.cells must be in [0, 256] (0: none), got {self.cells!r}")
        check(1 <= self.heading_bins <= 64, f"observation.belief_map.heading_bins must be in [1, 64], got {self.heading_bins!r}")
        check(self.frame in FRAMES, f"observation.belief_map.frame must be one of {', '.join(FRAMES)}, got {self.frame!r}")
        check(
            math.isfinite(self.extent_m) and self.extent_m > 0,
            f"observation.belief_map.extent_m must be finite and > 0, got {self.extent_m!r}",
        )

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(heading_bins, cells, cells)``: channels, rows (y), columns (x)."""
        return (self.heading_bins, self.cells, self.cells)


def _window(
    config: BeliefMapConfig, poses: NDArray[np.float64], w: NDArray[np.float64], estimate: PoseEstimate,
    bounds_m: tuple[float, float, float, float],
) -> tuple[float, float, float, float, float]:  # fmt: skip
    """``(x0, y0, theta0, side_x, side_y)``: the map's centre, its turn and its sides (module docstring)."""
    if config.frame == "world":
        xmin, ymin, xmax, ymax = bounds_m
        return (xmin + xmax) / 2, (ymin + ymax) / 2, 0.0, xmax - xmin, ymax - ymin
    if estimate.valid:
        return estimate.x_m, estimate.y_m, estimate.theta_rad, config.extent_m, config.extent_m
    x0, y0 = w @ poses[:, 0], w @ poses[:, 1]
    theta0 = math.atan2(float(w @ np.sin(poses[:, 2])), float(w @ np.cos(poses[:, 2])))
    return float(x0), float(y0), theta0, config.extent_m, config.extent_m


def _in_window(
    xy: NDArray[np.float64], theta: NDArray[np.float64], window: tuple[float, float, float, float, float]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World positions ``(n, 2)`` and headings ``(n,)`` in the window's frame, positions over its sides
    (so the window is ``[-0.5, 0.5)`` on each axis), headings wrapped into ``[-pi, pi)``."""
    x0, y0, theta0, side_x, side_y = window
    c, s = math.cos(theta0), math.sin(theta0)
    dx, dy = xy[:, 0] - x0, xy[:, 1] - y0
    u = (c * dx + s * dy) / side_x
    v = (-s * dx + c * dy) / side_y
    rel = np.mod(theta - theta0 + math.pi, 2 * math.pi) - math.pi
    return np.stack([u, v], axis=1), rel


def _cell(unit: NDArray[np.float64], cells: int) -> NDArray[np.intp]:
    """The cell index of window coordinates in ``[-0.5, 0.5)``, outside ones in the nearest border cell."""
    return np.clip(np.floor((unit + 0.5) * cells), 0, cells - 1).astype(np.intp)


def _histogram(
    config: BeliefMapConfig, poses: NDArray[np.float64], w: NDArray[np.float64],
    window: tuple[float, float, float, float, float],
) -> NDArray[np.float64]:  # fmt: skip
    unit, rel = _in_window(poses[:, :2], poses[:, 2], window)
    col, row = _cell(unit[:, 0], config.cells), _cell(unit[:, 1], config.cells)
    channel = np.minimum(((rel + math.pi) / (2 * math.pi) * config.heading_bins).astype(np.intp), config.heading_bins - 1)
    flat = (channel * config.cells + row) * config.cells + col
    counts = np.asarray(np.bincount(flat, weights=w, minlength=int(np.prod(config.shape))), dtype=np.float64)
    return counts.reshape(config.shape)


def _normal_cdf(z: NDArray[np.float64]) -> NDArray[np.float64]:
    erf = np.array([math.erf(v / math.sqrt(2.0)) for v in z.ravel()]).reshape(z.shape)
    return 0.5 * (1.0 + erf)


def _gaussian(
    config: BeliefMapConfig, estimate: PoseEstimate, window: tuple[float, float, float, float, float]
) -> NDArray[np.float64]:
    """The estimate's Gaussian at the cell centres times its heading bins' probabilities (module docstring)."""
    x0, y0, theta0, side_x, side_y = window
    centres = (np.arange(config.cells) + 0.5) / config.cells - 0.5
    c, s = math.cos(theta0), math.sin(theta0)
    # cell centres in the world: the window's axes turned by theta0
    u, v = np.meshgrid(centres * side_x, centres * side_y)  # rows: v (y), columns: u (x)
    wx, wy = x0 + c * u - s * v, y0 + s * u + c * v
    cov = estimate.covariance[:2, :2]
    inv = np.linalg.inv(cov)
    dx, dy = wx - estimate.x_m, wy - estimate.y_m
    density = np.exp(-0.5 * (inv[0, 0] * dx * dx + 2 * inv[0, 1] * dx * dy + inv[1, 1] * dy * dy))
    edges = np.linspace(-math.pi, math.pi, config.heading_bins + 1)
    mean = float(np.mod(estimate.theta_rad - theta0 + math.pi, 2 * math.pi) - math.pi)
    sd = math.sqrt(float(estimate.covariance[2, 2]))
    if sd > 0:
        turns = np.array([-2 * math.pi, 0.0, 2 * math.pi])[:, None]
        cdf = _normal_cdf((edges[None, :] - mean + turns) / sd)
        heading = (cdf[:, 1:] - cdf[:, :-1]).sum(axis=0)
    else:
        heading = np.zeros(config.heading_bins)
        heading[min(int((mean + math.pi) / (2 * math.pi) * config.heading_bins), config.heading_bins - 1)] = 1.0
    return heading[:, None, None] * density[None, :, :]


def _finite_gaussian(estimate: PoseEstimate) -> bool:
    cov = estimate.covariance
    if not (estimate.valid and cov.shape == (3, 3) and np.all(np.isfinite(cov)) and cov[2, 2] >= 0):
        return False
    xy = cov[:2, :2]
    return bool(xy[0, 0] > 0 and xy[1, 1] > 0 and np.linalg.det(xy) > 0)


def belief_map(
    config: BeliefMapConfig, overlay: Overlay, estimate: PoseEstimate, bounds_m: tuple[float, float, float, float]
) -> NDArray[np.float32]:
    """The belief map of one localizer state (module docstring): ``config.shape``, float32, summing to 1
    (all zeros without a hypothesis).

    Args:
        config: the map's size and frame.
        overlay: the localizer's hypotheses (:meth:`Localizer.overlay`).
        estimate: its estimate (the estimate frame's centre; a one-pose overlay's Gaussian).
        bounds_m: the world's ``(xmin, ymin, xmax, ymax)`` (the world frame's extent).
    """
    poses = np.asarray(overlay.poses, dtype=np.float64).reshape(-1, 3)
    weights = np.asarray(overlay.weights, dtype=np.float64).reshape(-1)
    finite = np.all(np.isfinite(poses), axis=1) & np.isfinite(weights) & (weights > 0) if weights.shape == (len(poses),) else None
    if finite is None or not finite.any():
        return np.zeros(config.shape, dtype=np.float32)
    poses, weights = poses[finite], weights[finite]
    w = weights / weights.sum()
    window = _window(config, poses, w, estimate, bounds_m)
    if len(poses) == 1 and _finite_gaussian(estimate):
        grid = _gaussian(config, estimate, window)
        total = grid.sum()
        if total > 0:
            return (grid / total).astype(np.float32)
    return _histogram(config, poses, w, window).astype(np.float32)
