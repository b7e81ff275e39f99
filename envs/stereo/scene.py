"""The world as a forward camera sees it: flat arrays for the renderer and the fast mode.

**Static scene** (:class:`StaticScene`, built once per world by :func:`static_scene`): every
static segment of the world (:meth:`envs.config.WorldConfig.static_segments`: the boundary
fence, walls, furniture, then the sides of the features' solids in the same order) with its
height interval and appearance: a flat colour, or a façade profile
(:class:`envs.features.base.FacadeProfile`) flattened into arrays. Sides of one convex solid
are consecutive and form an *object* (for silhouettes). The vertical edges inside the façades
(:meth:`~envs.features.base.FacadeProfile.edges`) are listed as world points with their height
runs and the colours either side.

**Moving scene**: the bodies' parts as :meth:`envs.figures.Figures.appearance` gives them
(discs for people, box sides for cars), each step.

**Camera geometry** (:class:`Rig`): three level pinhole cameras in a row, ``baseline_m``
apart, the middle one ``forward_m`` ahead of the robot's centre at ``height_m``. Pixel
column ``k`` spans ``[k, k + 1)`` and its ray goes through its centre ``k + 0.5`` (the
convention of :mod:`envs.stereo.vision`): a point at ``(right X, forward Z, height z)``
in a camera's frame is at ``u = cx + f X / Z``, ``v = cy - f (z - height) / Z``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from envs.config import WorldConfig

#: the colour of static segments without an appearance of their own (the boundary fence, walls, furniture)
PLAIN_RGB = (150, 148, 140)

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


class Rig(NamedTuple):
    """Three level, parallel, identical pinhole cameras in a row (left, middle, right).

    Attributes:
        focal_px, cx_px, cy_px: focal length and principal point (continuous pixel coordinates).
        width_px, height_px: image size.
        height_m: the cameras' height above the floor.
        forward_m: the middle camera ahead of the robot's centre; ``baseline_m``: between neighbours.
    """

    focal_px: float
    cx_px: float
    cy_px: float
    width_px: int
    height_px: int
    height_m: float
    forward_m: float
    baseline_m: float

    def cameras(self, pose: Array) -> tuple[Array, Array]:
        """``(3, 2)`` the cameras' positions (left, middle, right) for robot ``pose`` ``(3,)``, and
        ``(2,)`` their common forward unit vector."""
        c, s = math.cos(float(pose[2])), math.sin(float(pose[2]))
        forward = np.array([c, s])
        left = np.array([-s, c])
        centre = np.asarray(pose[:2], dtype=np.float64) + self.forward_m * forward
        lateral = np.array([self.baseline_m, 0.0, -self.baseline_m])
        return centre + lateral[:, None] * left, forward

    def cameras_at(self, poses: Array) -> tuple[Array, Array]:
        """``(3, 2)`` each camera's position and ``(3, 2)`` its forward unit vector, camera ``j``
        (left, middle, right) on the rig when the robot held ``poses[j]`` ``(3, 3)``: cameras that
        take their frames at different times (unsynchronised webcams on a moving robot)."""
        xy = np.empty((3, 2))
        forward = np.empty((3, 2))
        for j in range(3):
            cams, fwd = self.cameras(poses[j])
            xy[j] = cams[j]
            forward[j] = fwd
        return xy, forward

    @property
    def hfov_rad(self) -> float:
        """The horizontal field of view."""
        return 2.0 * math.atan(0.5 * self.width_px / self.focal_px)


class StaticScene(NamedTuple):
    """The static world for a camera (module docstring). ``S`` segments, ``NP`` façade profiles,
    ``G`` façade intervals, ``R`` runs, ``O`` objects, ``E`` façade edges.

    Attributes:
        seg_a, seg_b: ``(S, 2)``; ``seg_z0``, ``seg_z1``: ``(S,)`` heights spanned;
            ``seg_rgb``: ``(S, 3)`` flat colour; ``seg_profile``: ``(S,)`` façade profile or -1;
            ``seg_length``: ``(S,)``; ``seg_object``: ``(S,)`` the convex solid it belongs to or -1;
            ``seg_floor``: ``(S,)`` whether its solid stands on the floor (its back faces are
            hidden from a camera lower than its top).
        prof_first: ``(NP + 1,)`` each profile's first interval; ``int_s0``, ``int_s1``: ``(G,)``
            the intervals along the side; ``int_first_run``: ``(G + 1,)``; ``run_z0``,
            ``run_z1``: ``(R,)``; ``run_rgb``: ``(R, 3)``.
        obj_first, obj_count: ``(O,)`` each object's first segment and side count.
        brk_xy: ``(E, 2)`` the façades' breaks (vertical edges) as world points, grouped by side:
            side ``i``'s are ``seg_first_brk[i]:seg_first_brk[i + 1]`` (``(S + 1,)``);
            ``brk_first_run``: ``(E + 1,)`` each break's runs: ``brun_z0``, ``brun_z1`` the
            heights and ``brun_left``, ``brun_right`` ``(R', 3)`` the colours left and right of the
            break seen from outside, where they differ.
    """

    seg_a: Array
    seg_b: Array
    seg_z0: Array
    seg_z1: Array
    seg_rgb: Array
    seg_profile: IntArray
    seg_length: Array
    seg_object: IntArray
    seg_floor: NDArray[np.bool_]
    prof_first: IntArray
    int_s0: Array
    int_s1: Array
    int_first_run: IntArray
    run_z0: Array
    run_z1: Array
    run_rgb: Array
    obj_first: IntArray
    obj_count: IntArray
    seg_first_brk: IntArray
    brk_xy: Array
    brk_first_run: IntArray
    brun_z0: Array
    brun_z1: Array
    brun_left: Array
    brun_right: Array


@numba.njit(cache=True)
def facade_interval(p: int, s: float, prof_first: IntArray, int_s1: Array) -> int:
    """The interval of façade profile ``p`` that holds ``s`` metres along its side (clamped to
    the first and last): the first ``g`` in ``prof_first[p]:prof_first[p + 1]`` with
    ``s < int_s1[g]`` (a binary search)."""
    lo = prof_first[p]
    hi = prof_first[p + 1] - 1  # the last interval takes everything beyond
    while lo < hi:
        mid = (lo + hi) // 2
        if s >= int_s1[mid]:
            lo = mid + 1
        else:
            hi = mid
    return lo


def static_scene(world: WorldConfig) -> StaticScene:
    """Pack the static world of ``world`` for a camera (module docstring)."""
    segments = world.static_segments()
    solids = [solid for feature in world.features.values() for solid in feature.solids()]
    plain = segments.shape[0] - sum(solid.corners.shape[0] for solid in solids)
    count = segments.shape[0]
    seg_rgb = np.tile(np.asarray(PLAIN_RGB, dtype=np.float64), (count, 1))
    seg_profile = np.full(count, -1, dtype=np.int64)
    seg_object = np.full(count, -1, dtype=np.int64)
    seg_floor = np.zeros(count, dtype=np.bool_)
    prof_first = [0]
    int_s0: list[float] = []
    int_s1: list[float] = []
    int_first_run = [0]
    run_z0: list[float] = []
    run_z1: list[float] = []
    run_rgb: list[NDArray[np.float64]] = []
    obj_first, obj_count = [], []
    seg_first_brk = [0] * (plain + 1)
    brk_xy: list[tuple[float, float]] = []
    brk_first_run = [0]
    brun: list[tuple[float, float, tuple[float, ...], tuple[float, ...]]] = []
    row = plain
    for o, solid in enumerate(solids):
        sides = solid.corners.shape[0]
        obj_first.append(row)
        obj_count.append(sides)
        for i in range(sides):
            s = row + i
            seg_rgb[s] = solid.rgb
            seg_object[s] = o
            seg_floor[s] = solid.bottom_m <= 0.0
            profile = solid.facades[i] if solid.facades else None
            if profile is not None:
                seg_profile[s] = len(prof_first) - 1
                breaks = profile.breaks_s
                for k in range(breaks.size - 1):
                    int_s0.append(float(breaks[k]))
                    int_s1.append(float(breaks[k + 1]))
                    lo, hi = int(profile.run_index[k]), int(profile.run_index[k + 1])
                    run_z0.extend(profile.run_z[lo:hi, 0].tolist())
                    run_z1.extend(profile.run_z[lo:hi, 1].tolist())
                    run_rgb.extend(profile.run_rgb[lo:hi])
                    int_first_run.append(len(run_z0))
                prof_first.append(len(int_s0))
                a, b = segments[s, 0:2], segments[s, 2:4]
                length = float(np.hypot(*(b - a)))
                last = None
                for e_s, z0, z1, left, right in profile.edges():  # sorted by s: one break per distinct s
                    if e_s != last:
                        x, y = a + (b - a) * (e_s / length)
                        brk_xy.append((float(x), float(y)))
                        brk_first_run.append(brk_first_run[-1])
                        last = e_s
                    brun.append((z0, z1, left, right))
                    brk_first_run[-1] += 1
            seg_first_brk.append(len(brk_xy))
        row += sides
    assert row == count, "the features' solids and their segments disagree"
    seg_a = np.ascontiguousarray(segments[:, 0:2])
    seg_b = np.ascontiguousarray(segments[:, 2:4])
    scene = StaticScene(
        seg_a,
        seg_b,
        np.ascontiguousarray(segments[:, 4]),
        np.ascontiguousarray(segments[:, 5]),
        seg_rgb,
        seg_profile,
        np.hypot(*(seg_b - seg_a).T),
        seg_object,
        seg_floor,
        np.asarray(prof_first, dtype=np.int64),
        np.asarray(int_s0, dtype=np.float64),
        np.asarray(int_s1, dtype=np.float64),
        np.asarray(int_first_run, dtype=np.int64),
        np.asarray(run_z0, dtype=np.float64),
        np.asarray(run_z1, dtype=np.float64),
        np.asarray(run_rgb, dtype=np.float64).reshape(-1, 3),
        np.asarray(obj_first, dtype=np.int64),
        np.asarray(obj_count, dtype=np.int64),
        np.asarray(seg_first_brk, dtype=np.int64),
        np.asarray(brk_xy, dtype=np.float64).reshape(-1, 2),
        np.asarray(brk_first_run, dtype=np.int64),
        np.asarray([r[0] for r in brun], dtype=np.float64),
        np.asarray([r[1] for r in brun], dtype=np.float64),
        np.asarray([r[2] for r in brun], dtype=np.float64).reshape(-1, 3),
        np.asarray([r[3] for r in brun], dtype=np.float64).reshape(-1, 3),
    )
    for array in scene:
        array.setflags(write=False)
    return scene
