"""The image mode: a column ray caster over the 2.5-D world (numba).

Every pixel column of a level pinhole camera looks along one horizontal ray; what it shows at
each row is the nearest thing along that ray whose height interval holds the row's line of
sight there. So the renderer

1. *splats* every segment (the static sides with their façades, the cars' box sides) and disc
   (people's legs, torsos, heads) within range into the columns it covers, recording for
   each column every crossing: its depth (the forward distance ``Z``, the ray being
   ``(t Z, Z)`` with ``t = (k + 0.5 - cx) / f`` in the camera's (right, forward) frame), the
   heights it spans and where to read its colour;
2. *fills* each column near to far: a crossing at depth ``Z`` spanning ``[z0, z1)`` covers
   the rows whose centres lie in ``[cy - f (z1 - h) / Z, cy - f (z0 - h) / Z)`` and paints
   those still empty (a near car hides a building's lower floors, the building rises above it);
3. paints what is left sky (above the horizon, a gradient) or ground (below it),

with the exposure gain and the pixel noise applied as each pixel is written. Back faces of
solids that stand on the floor and reach above the camera can never show and are skipped;
a tree's crown, which starts above the trunk, keeps them (a rising line of sight can enter
it from below).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from envs.stereo.scene import StaticScene, facade_interval

#: crossings kept per column (the nearest, when more cross it)
MAX_HITS = 32
NEAR_M = 0.05  # the near clipping plane
TALL_M = 1e6  # heights are clipped to this (walls and columns may reach infinitely high)
SKY_TOP_RGB = (92, 132, 196)
SKY_HORIZON_RGB = (176, 200, 226)
GROUND_RGB = (112, 110, 104)

Array = NDArray[np.float64]
#: the moving bodies as the renderer takes them: box sides (a, b, z0, z1, rgb), then discs (xy, r, z0, z1, rgb)
Moving = tuple[Array, Array, Array, Array, Array, Array, Array, Array, Array, Array]


@numba.njit(cache=True, inline="always")
def _insert(hits_z: Array, hits_ref: NDArray[np.int64], hits_s: Array, count: NDArray[np.int64], k: int, z: float, ref: int,
            s: float) -> None:  # fmt: skip
    """Record a crossing at depth ``z`` in column ``k`` (replacing the farthest when the column is full)."""
    n = count[k]
    if n < MAX_HITS:
        hits_z[k, n] = z
        hits_ref[k, n] = ref
        hits_s[k, n] = s
        count[k] = n + 1
        return
    far = 0
    for i in range(1, MAX_HITS):
        if hits_z[k, i] > hits_z[k, far]:
            far = i
    if z < hits_z[k, far]:
        hits_z[k, far] = z
        hits_ref[k, far] = ref
        hits_s[k, far] = s


@numba.njit(cache=True)
def _splat_segments(
    cam: Array, fwd: Array, focal: float, cx: float, width: int, max_range: float,
    seg_a: Array, seg_b: Array, cull: NDArray[np.bool_], ref_offset: int,
    hits_z: Array, hits_ref: NDArray[np.int64], hits_s: Array, count: NDArray[np.int64],
) -> None:  # fmt: skip
    """Record every segment's crossing in the columns it covers; ``cull[i]``: skip segment
    ``i`` when the camera is behind it (on the left of ``a -> b``, inside a counter-clockwise
    solid's side); crossings refer to segment ``ref_offset + i``; ``hits_s``: the distance from
    ``a`` along the segment."""
    fx, fy = fwd[0], fwd[1]
    rx, ry = fy, -fx  # the camera's right
    for i in range(seg_a.shape[0]):
        ax = seg_a[i, 0] - cam[0]
        ay = seg_a[i, 1] - cam[1]
        bx = seg_b[i, 0] - cam[0]
        by = seg_b[i, 1] - cam[1]
        if cull[i]:
            # outward normal of a counter-clockwise side a -> b is (dy, -dx); front faces have the camera on its side
            if -ax * (by - ay) + ay * (bx - ax) <= 0.0:
                continue
        xa = ax * rx + ay * ry
        za = ax * fx + ay * fy
        xb = bx * rx + by * ry
        zb = bx * fx + by * fy
        if (za < NEAR_M and zb < NEAR_M) or (za > max_range and zb > max_range):
            continue
        # clip to the near plane for the column range
        ca_x, ca_z, cb_x, cb_z = xa, za, xb, zb
        if ca_z < NEAR_M:
            t = (NEAR_M - za) / (zb - za)
            ca_x = xa + t * (xb - xa)
            ca_z = NEAR_M
        elif cb_z < NEAR_M:
            t = (NEAR_M - za) / (zb - za)
            cb_x = xa + t * (xb - xa)
            cb_z = NEAR_M
        ua = cx + focal * ca_x / ca_z
        ub = cx + focal * cb_x / cb_z
        lo = min(ua, ub)
        hi = max(ua, ub)
        k0 = max(0, int(math.ceil(lo - 0.5)))
        k1 = min(width - 1, int(math.floor(hi - 0.5)))
        dx = xb - xa
        dz = zb - za
        length = math.sqrt((seg_b[i, 0] - seg_a[i, 0]) ** 2 + (seg_b[i, 1] - seg_a[i, 1]) ** 2)
        for k in range(k0, k1 + 1):
            tk = (k + 0.5 - cx) / focal
            denom = dx - tk * dz
            if denom == 0.0:
                continue
            lam = (tk * za - xa) / denom
            if lam < 0.0 or lam > 1.0:
                continue
            z = za + lam * dz
            if z < NEAR_M or z > max_range:
                continue
            _insert(hits_z, hits_ref, hits_s, count, k, z, ref_offset + i, lam * length)


@numba.njit(cache=True)
def _splat_discs(
    cam: Array, fwd: Array, focal: float, cx: float, width: int, max_range: float,
    centres: Array, radii: Array, ref_offset: int,
    hits_z: Array, hits_ref: NDArray[np.int64], hits_s: Array, count: NDArray[np.int64],
) -> None:  # fmt: skip
    """Record every disc's near crossing in the columns its silhouette covers."""
    fx, fy = fwd[0], fwd[1]
    rx, ry = fy, -fx
    for i in range(centres.shape[0]):
        px = centres[i, 0] - cam[0]
        py = centres[i, 1] - cam[1]
        xc = px * rx + py * ry
        zc = px * fx + py * fy
        r = radii[i]
        if zc - r < NEAR_M or zc - r > max_range:
            continue  # behind, cut by the near plane (a body against the lens), or too far
        # tangent slopes: (zc^2 - r^2) t^2 - 2 xc zc t + (xc^2 - r^2) = 0
        a = zc * zc - r * r
        disc = xc * xc + zc * zc - r * r
        if a <= 0.0 or disc <= 0.0:
            continue
        root = r * math.sqrt(disc)
        t_lo = (xc * zc - root) / a
        t_hi = (xc * zc + root) / a
        k0 = max(0, int(math.ceil(cx + focal * t_lo - 0.5)))
        k1 = min(width - 1, int(math.floor(cx + focal * t_hi - 0.5)))
        for k in range(k0, k1 + 1):
            tk = (k + 0.5 - cx) / focal
            q = 1.0 + tk * tk
            b = tk * xc + zc
            d = b * b - q * (xc * xc + zc * zc - r * r)
            if d < 0.0:
                continue
            z = (b - math.sqrt(d)) / q
            if z < NEAR_M:
                continue
            _insert(hits_z, hits_ref, hits_s, count, k, z, ref_offset + i, 0.0)


@numba.njit(cache=True)
def _fill(
    image: NDArray[np.uint8], focal: float, cy: float, cam_h: float,
    hits_z: Array, hits_ref: NDArray[np.int64], hits_s: Array, count: NDArray[np.int64],
    ref_z0: Array, ref_z1: Array, ref_rgb: Array, ref_profile: NDArray[np.int64],
    prof_first: NDArray[np.int64], int_s0: Array, int_s1: Array, int_first_run: NDArray[np.int64],
    run_z0: Array, run_z1: Array, run_rgb: Array, background: Array,
    gain: Array, noise: NDArray[np.float32],
) -> None:  # fmt: skip
    """Paint every column near to far, then the ``background`` ``(H, 3)`` (sky, ground) where
    nothing stands (module docstring); each pixel value is ``clip(round(gain[c] * colour[c] +
    noise))``, ``gain`` ``(3,)`` one per channel, ``noise`` one value per pixel and channel in image
    order (or a single value for all)."""
    height, width = image.shape[0], image.shape[1]
    filled = np.zeros(height, dtype=np.bool_)
    order = np.empty(MAX_HITS, dtype=np.int64)
    noisy = noise.shape[0] > 1
    colour = np.empty(3)
    for k in range(width):
        n = count[k]
        # insertion sort of the crossings by depth
        for i in range(n):
            order[i] = i
        for i in range(1, n):
            j = i
            while j > 0 and hits_z[k, order[j - 1]] > hits_z[k, order[j]]:
                tmp = order[j - 1]
                order[j - 1] = order[j]
                order[j] = tmp
                j -= 1
        filled[:] = False
        left = height
        for i in range(n):
            if left == 0:
                break
            h = order[i]
            z = hits_z[k, h]
            ref = hits_ref[k, h]
            v_top = cy - focal * (min(ref_z1[ref], TALL_M) - cam_h) / z  # (a wall of infinite height)
            v_bot = cy - focal * (max(ref_z0[ref], -TALL_M) - cam_h) / z
            r0 = max(0, int(math.ceil(v_top - 0.5)))
            r1 = min(height - 1, int(math.ceil(v_bot - 0.5)) - 1)
            if r1 < r0:
                continue
            p = ref_profile[ref]
            run = -1
            run_end = -1
            if p >= 0:  # a façade: the interval of this column's point along the side
                g = facade_interval(p, hits_s[k, h], prof_first, int_s1)
                run = int_first_run[g + 1] - 1  # walking down from the top run
                run_end = int_first_run[g]
            else:
                for c in range(3):
                    colour[c] = gain[c] * ref_rgb[ref, c]
            for r in range(r0, r1 + 1):
                if filled[r]:
                    continue
                filled[r] = True
                left -= 1
                if p >= 0:
                    zr = cam_h + (cy - (r + 0.5)) * z / focal
                    while run > run_end and zr < run_z0[run]:
                        run -= 1
                    for c in range(3):
                        colour[c] = gain[c] * run_rgb[run, c]
                base = (r * width + k) * 3
                for c in range(3):
                    value = colour[c] + (noise[base + c] if noisy else noise[0])
                    image[r, k, c] = min(255, max(0, int(value + 0.5)))
        if left == 0:
            continue
        for r in range(height):
            if filled[r]:
                continue
            base = (r * width + k) * 3
            for c in range(3):
                value = gain[c] * background[r, c] + (noise[base + c] if noisy else noise[0])
                image[r, k, c] = min(255, max(0, int(value + 0.5)))


def background_rows(height_px: int, cy_px: float) -> Array:
    """``(H, 3)`` the colour of each row where nothing stands: a sky darkening upward above the
    horizon (row centres above ``cy_px``), the ground below."""
    centre = np.arange(height_px) + 0.5
    w = np.clip(centre / cy_px, 0.0, 1.0)[:, None]
    sky = np.asarray(SKY_TOP_RGB, dtype=np.float64) + (np.asarray(SKY_HORIZON_RGB, dtype=np.float64) - SKY_TOP_RGB) * w
    return np.where((centre < cy_px)[:, None], sky, np.asarray(GROUND_RGB, dtype=np.float64))


class ColumnRenderer:
    """Renders the images of a camera over a static scene and the moving bodies (module docstring).

    Args:
        scene: the static scene; ``focal_px``, ``cx_px``, ``cy_px``: the intrinsics;
        width_px, height_px: the image size; ``height_m``: the camera's height;
        max_range_m: nothing farther is drawn.
    """

    def __init__(
        self, scene: StaticScene, focal_px: float, cx_px: float, cy_px: float, width_px: int, height_px: int,
        height_m: float, max_range_m: float,
    ) -> None:  # fmt: skip
        self.scene = scene
        self.focal, self.cx, self.cy = float(focal_px), float(cx_px), float(cy_px)
        self.width, self.height = int(width_px), int(height_px)
        self.cam_h = float(height_m)
        self.max_range = float(max_range_m)
        # back faces of solids that stand on the floor and reach above the camera never show
        self._cull = np.ascontiguousarray(scene.seg_floor & (scene.seg_z1 >= self.cam_h))
        self._hits_z = np.empty((self.width, MAX_HITS))
        self._hits_ref = np.empty((self.width, MAX_HITS), dtype=np.int64)
        self._hits_s = np.empty((self.width, MAX_HITS))
        self._count = np.zeros(self.width, dtype=np.int64)
        self._static_count = scene.seg_a.shape[0]
        self._no_noise = np.zeros(1, dtype=np.float32)
        self.background = background_rows(self.height, self.cy)

    def render(
        self,
        cam_xy: Array,
        forward: Array,
        moving: Moving,
        gain: float | Array = 1.0,
        noise: NDArray[np.float32] | None = None,
    ) -> NDArray[np.uint8]:
        """The ``(H, W, 3)`` image from ``cam_xy`` ``(2,)`` looking along ``forward`` (unit ``(2,)``).

        Args:
            moving: the moving bodies: box sides ``(a, b, z0, z1, rgb)`` and discs ``(xy, r, z0, z1, rgb)``.
            gain: the exposure gain, one number or ``(3,)`` one per channel (a white balance);
                ``noise``: ``(H W 3,)`` pixel noise in image order (None: none).
        """
        sc = self.scene
        side_a, side_b, side_z0, side_z1, side_rgb, disc_xy, disc_r, disc_z0, disc_z1, disc_rgb = moving
        self._count[:] = 0
        cam = np.ascontiguousarray(cam_xy, dtype=np.float64)
        fwd = np.ascontiguousarray(forward, dtype=np.float64)
        args = (self.focal, self.cx, self.width, self.max_range)
        buffers = (self._hits_z, self._hits_ref, self._hits_s, self._count)
        _splat_segments(cam, fwd, *args, sc.seg_a, sc.seg_b, self._cull, 0, *buffers)
        n_static = self._static_count
        n_sides = side_a.shape[0]
        if n_sides:
            _splat_segments(cam, fwd, *args, side_a, side_b, np.zeros(n_sides, dtype=np.bool_), n_static, *buffers)
        if disc_xy.shape[0]:
            _splat_discs(cam, fwd, *args, disc_xy, disc_r, n_static + n_sides, *buffers)
        ref_z0 = np.concatenate((sc.seg_z0, side_z0, disc_z0))
        ref_z1 = np.concatenate((sc.seg_z1, side_z1, disc_z1))
        ref_rgb = np.concatenate((sc.seg_rgb, side_rgb, disc_rgb))
        ref_profile = np.concatenate((sc.seg_profile, np.full(n_sides + disc_xy.shape[0], -1, dtype=np.int64)))
        image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        _fill(image, self.focal, self.cy, self.cam_h, *buffers, ref_z0, ref_z1, ref_rgb, ref_profile,
              sc.prof_first, sc.int_s0, sc.int_s1, sc.int_first_run, sc.run_z0, sc.run_z1, sc.run_rgb, self.background,
              np.broadcast_to(np.asarray(gain, dtype=np.float64), (3,)).copy(),
              self._no_noise if noise is None else noise)  # fmt: skip
        return image
