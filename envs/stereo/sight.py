"""Lines of sight of the fast mode's middle camera: what a column meets, what hides what.

The geometric edge finder (:mod:`envs.stereo.geometric`) asks, for an image column and a depth,
which heights at that depth nearer things hide (:func:`blockers`), and what the column shows
beyond it, behind a silhouette (:func:`column_behind`, :func:`mean_behind`). Everything a line
of sight can meet (the static segments, the moving boxes' sides, the discs) is packed once per
frame in the camera's frame and binned by column (:func:`entries`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from envs.stereo.render import NEAR_M, TALL_M
from envs.stereo.scene import facade_interval

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

_EPS_M = 1e-3
#: bins of columns for the line-of-sight queries
_BIN_PX = 8
SEGMENT, DISC = 0, 1


@numba.njit(cache=True)
def entries(
    cam: Array, fwd: Array, focal: float, cx: float, width: int, max_range: float,
    seg_a: Array, seg_b: Array, seg_z0: Array, seg_z1: Array, cull: NDArray[np.bool_],
    disc_xy: Array, disc_r: Array, disc_z0: Array, disc_z1: Array,
) -> tuple[Array, IntArray, IntArray, IntArray, IntArray]:  # fmt: skip
    """Everything a line of sight can meet, in the camera's (right X, forward Z) frame, binned by column.

    Returns:
        geometry ``(N, 7)``: ``(x0, z0, x1, z1, height bottom, height top, nearest depth)``
        (a segment's ends, or a disc's centre and radius in ``x1``); ``kind`` ``(N,)``
        (SEGMENT, DISC); ``ref`` ``(N,)`` (segment or disc index); the bins of columns as CSR
        ``first`` ``(B + 1,)`` and ``members``, each bin sorted by nearest depth.
    """
    n_seg = seg_a.shape[0]
    n_disc = disc_xy.shape[0]
    total = n_seg + n_disc
    geom = np.empty((total, 7))
    kind = np.empty(total, dtype=np.int64)
    ref = np.empty(total, dtype=np.int64)
    k_lo = np.empty(total, dtype=np.int64)
    k_hi = np.empty(total, dtype=np.int64)
    fx, fy = fwd[0], fwd[1]
    rx, ry = fy, -fx
    n = 0
    for i in range(n_seg):
        ax = seg_a[i, 0] - cam[0]
        ay = seg_a[i, 1] - cam[1]
        bx = seg_b[i, 0] - cam[0]
        by = seg_b[i, 1] - cam[1]
        if cull[i] and -ax * (by - ay) + ay * (bx - ax) <= 0.0:
            continue
        xa = ax * rx + ay * ry
        za = ax * fx + ay * fy
        xb = bx * rx + by * ry
        zb = bx * fx + by * fy
        if (za < NEAR_M and zb < NEAR_M) or (za > max_range and zb > max_range):
            continue
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
        lo = max(0.0, min(ua, ub))
        hi = min(width - 1e-9, max(ua, ub))
        if hi < lo:
            continue
        geom[n, 0] = xa
        geom[n, 1] = za
        geom[n, 2] = xb
        geom[n, 3] = zb
        geom[n, 4] = seg_z0[i]
        geom[n, 5] = seg_z1[i]
        geom[n, 6] = min(ca_z, cb_z)
        kind[n] = SEGMENT
        ref[n] = i
        k_lo[n] = int(lo) // _BIN_PX
        k_hi[n] = int(hi) // _BIN_PX
        n += 1
    for i in range(n_disc):
        px = disc_xy[i, 0] - cam[0]
        py = disc_xy[i, 1] - cam[1]
        xc = px * rx + py * ry
        zc = px * fx + py * fy
        r = disc_r[i]
        if zc - r < NEAR_M or zc - r > max_range:
            continue
        a = zc * zc - r * r
        d = xc * xc + zc * zc - r * r
        if a <= 0.0 or d <= 0.0:
            continue
        root = r * math.sqrt(d)
        lo = max(0.0, cx + focal * (xc * zc - root) / a)
        hi = min(width - 1e-9, cx + focal * (xc * zc + root) / a)
        if hi < lo:
            continue
        geom[n, 0] = xc
        geom[n, 1] = zc
        geom[n, 2] = r
        geom[n, 3] = 0.0
        geom[n, 4] = disc_z0[i]
        geom[n, 5] = disc_z1[i]
        geom[n, 6] = zc - r
        kind[n] = DISC
        ref[n] = i
        k_lo[n] = int(lo) // _BIN_PX
        k_hi[n] = int(hi) // _BIN_PX
        n += 1
    bins = (width + _BIN_PX - 1) // _BIN_PX
    first = np.zeros(bins + 1, dtype=np.int64)
    for e in range(n):
        for b in range(k_lo[e], k_hi[e] + 1):
            first[b + 1] += 1
    for b in range(bins):
        first[b + 1] += first[b]
    fill = first[:-1].copy()
    members = np.empty(first[bins], dtype=np.int64)
    for e in range(n):
        for b in range(k_lo[e], k_hi[e] + 1):
            members[fill[b]] = e
            fill[b] += 1
    for b in range(bins):  # insertion sort by nearest depth
        for i in range(first[b] + 1, first[b + 1]):
            j = i
            while j > first[b] and geom[members[j - 1], 6] > geom[members[j], 6]:
                tmp = members[j - 1]
                members[j - 1] = members[j]
                members[j] = tmp
                j -= 1
    return geom[:n], kind[:n].copy(), ref[:n].copy(), first, members


@numba.njit(cache=True, inline="always")
def _crossing(geom: Array, kind: int, e: int, t: float) -> tuple[float, float]:
    """Depth and distance along the segment (0 for a disc) where the line ``X = t Z`` meets entry
    ``e`` (the near crossing of a disc), depth -1 where it does not."""
    if kind == SEGMENT:
        xa, za, xb, zb = geom[e, 0], geom[e, 1], geom[e, 2], geom[e, 3]
        dx = xb - xa
        dz = zb - za
        denom = dx - t * dz
        if denom == 0.0:
            return -1.0, 0.0
        lam = (t * za - xa) / denom
        if lam < 0.0 or lam > 1.0:
            return -1.0, 0.0
        return za + lam * dz, lam
    xc, zc, r = geom[e, 0], geom[e, 1], geom[e, 2]
    q = 1.0 + t * t
    b = t * xc + zc
    d = b * b - q * (xc * xc + zc * zc - r * r)
    if d < 0.0:
        return -1.0, 0.0
    return (b - math.sqrt(d)) / q, 0.0


MAX_BLOCKERS = 16


@numba.njit(cache=True)
def _cover(lo: Array, hi: Array, n: int, a: float, c: float) -> int:
    """Add ``[a, c)`` to the ``n`` disjoint intervals ``[lo, hi)`` sorted upward, merging what it
    touches; returns the new count (an interval beyond the arrays' room is dropped)."""
    i = 0
    while i < n and hi[i] < a:
        i += 1
    j = i
    while j < n and lo[j] <= c:
        a = min(a, lo[j])
        c = max(c, hi[j])
        j += 1
    if j == i:  # no overlap: shift right and insert
        if n == lo.shape[0]:
            return n
        for q in range(n, i, -1):
            lo[q] = lo[q - 1]
            hi[q] = hi[q - 1]
        lo[i] = a
        hi[i] = c
        return n + 1
    lo[i] = a  # intervals i..j-1 merge into one
    hi[i] = c
    shift = j - i - 1
    for q in range(i + 1, n - shift):
        lo[q] = lo[q + shift]
        hi[q] = hi[q + shift]
    return n - shift


@numba.njit(cache=True)
def blockers(
    u: float, depth: float, cam_h: float, focal: float, cx: float, geom: Array, kind: IntArray, first: IntArray,
    members: IntArray, lo: Array, hi: Array,
) -> int:  # fmt: skip
    """The heights at ``depth`` hidden from the camera along column ``u``, as disjoint intervals
    ``[lo, hi)`` sorted upward; returns their count.

    Something crossing the column at a nearer depth ``d`` over the heights ``[h0, h1)`` hides the
    heights ``[cam_h + (h0 - cam_h) depth / d, cam_h + (h1 - cam_h) depth / d)`` at ``depth``
    (the lines of sight that meet it)."""
    t = (u - cx) / focal
    b = int(u) // _BIN_PX
    n = 0
    if b < 0 or b >= first.shape[0] - 1:
        return 0
    limit = depth - _EPS_M
    for m in range(first[b], first[b + 1]):
        e = members[m]
        if geom[e, 6] >= limit:
            break  # sorted by nearest depth: nothing nearer follows
        d, _ = _crossing(geom, kind[e], e, t)
        if d <= NEAR_M or d >= limit:
            continue
        scale = depth / d
        h0 = max(geom[e, 4], -TALL_M)
        h1 = min(geom[e, 5], TALL_M)
        n = _cover(lo, hi, n, cam_h + (h0 - cam_h) * scale, cam_h + (h1 - cam_h) * scale)
    return n


MAX_PIECES = 64


@numba.njit(cache=True)
def column_behind(
    u: float, depth: float, max_range: float, cam_h: float, focal: float, cx: float, geom: Array, kind: IntArray,
    ref: IntArray, first: IntArray, members: IntArray, n_static: int, seg_profile: IntArray, seg_length: Array,
    seg_rgb: Array, side_rgb: Array, disc_rgb: Array, prof_first: IntArray, int_s1: Array, int_first_run: IntArray,
    run_z0: Array, run_z1: Array, run_rgb: Array, lo: Array, hi: Array, p_lo: Array, p_hi: Array, p_rgb: Array,
    scratch: Array, scratch_e: IntArray, span_lo: float, span_hi: float,
) -> tuple[int, int]:  # fmt: skip
    """Column ``u`` on both sides of ``depth`` in one pass: the heights at ``depth`` hidden by
    nearer things (as :func:`blockers`: ``[lo, hi)``), and what the column shows beyond
    ``depth`` (behind a silhouette) as pieces of height at ``depth`` (the lines of sight through
    them) with their colours, ``[p_lo, p_hi)`` and ``p_rgb`` ``(P, 3)``, near things first
    covering far ones (heights no piece covers show the sky or the ground), only within
    ``[span_lo, span_hi)`` (the silhouette's heights: nothing else is asked of the background).
    Returns both counts. ``scratch`` ``(5, 32)`` and ``scratch_e`` ``(32,)``: working room."""
    t = (u - cx) / focal
    b = int(u) // _BIN_PX
    if b < 0 or b >= first.shape[0] - 1:
        return 0, 0
    hit_d = scratch[0]
    hit_l = scratch[1]
    cov_lo = scratch[2, :MAX_BLOCKERS]
    cov_hi = scratch[3, :MAX_BLOCKERS]
    colour = scratch[4, :3]
    hit_e = scratch_e
    nh = 0
    nb = 0
    ncov = 0
    n = 0
    near = depth - _EPS_M
    m = first[b]
    end = first[b + 1]
    # The members come sorted by their nearest depth, so a crossing held in the buffer is the
    # nearest to come once the next member starts farther away: the background is built near
    # to far as the scan goes, and the scan stops once the span is covered (nothing farther
    # shows; every nearer thing, the blockers included, has been seen by then).
    while True:
        next_near = geom[members[m], 6] if m < end else math.inf
        while nh > 0 and hit_d[0] <= next_near:
            e = hit_e[0]
            scale = depth / hit_d[0]
            lam = hit_l[0]
            nh -= 1
            for q in range(nh):  # pop the front
                hit_d[q] = hit_d[q + 1]
                hit_e[q] = hit_e[q + 1]
                hit_l[q] = hit_l[q + 1]
            a = max(span_lo, cam_h + (max(geom[e, 4], -TALL_M) - cam_h) * scale)
            c = min(span_hi, cam_h + (min(geom[e, 5], TALL_M) - cam_h) * scale)
            if c <= a:
                continue
            n = _pieces(e, a, c, scale, lam, cam_h, kind, ref, n_static, seg_profile, seg_length, seg_rgb, side_rgb, disc_rgb,
                        prof_first, int_s1, int_first_run, run_z0, run_z1, run_rgb, cov_lo, cov_hi, ncov, p_lo, p_hi, p_rgb,
                        n, colour)  # fmt: skip
            ncov = _cover(cov_lo, cov_hi, ncov, a, c)
            if ncov == 1 and cov_lo[0] <= span_lo and cov_hi[0] >= span_hi:
                return nb, n  # the span is covered: farther things do not show
        if m >= end:
            break
        e = members[m]
        m += 1
        d, lam = _crossing(geom, kind[e], e, t)
        if NEAR_M < d < near:  # in front: hides part of the heights at depth
            scale = depth / d
            nb = _cover(lo, hi, nb, cam_h + (max(geom[e, 4], -TALL_M) - cam_h) * scale,
                        cam_h + (min(geom[e, 5], TALL_M) - cam_h) * scale)  # fmt: skip
            continue
        if d <= depth + _EPS_M or d > max_range or nh == 32:
            continue
        j = nh  # insertion by depth
        while j > 0 and hit_d[j - 1] > d:
            hit_d[j] = hit_d[j - 1]
            hit_e[j] = hit_e[j - 1]
            hit_l[j] = hit_l[j - 1]
            j -= 1
        hit_d[j] = d
        hit_e[j] = e
        hit_l[j] = lam
        nh += 1
    return nb, n


@numba.njit(cache=True)
def _pieces(
    e: int, a: float, c: float, scale: float, lam: float, cam_h: float, kind: IntArray, ref: IntArray, n_static: int,
    seg_profile: IntArray, seg_length: Array, seg_rgb: Array, side_rgb: Array, disc_rgb: Array, prof_first: IntArray,
    int_s1: Array, int_first_run: IntArray, run_z0: Array, run_z1: Array, run_rgb: Array, cov_lo: Array, cov_hi: Array,
    ncov: int, p_lo: Array, p_hi: Array, p_rgb: Array, n: int, colour: Array,
) -> int:  # fmt: skip
    """Add the parts of ``[a, c)`` (heights at the silhouette's depth) that entry ``e`` shows and
    nothing nearer covers (``[cov_lo, cov_hi)``) to the pieces, split by a façade's runs (its
    crossing at ``lam`` along it, ``scale`` = the silhouette's depth over the crossing's); returns the count."""
    i = ref[e]
    p = seg_profile[i] if kind[e] == SEGMENT and i < n_static else -1
    if p < 0:
        if kind[e] == DISC:
            for k in range(3):
                colour[k] = disc_rgb[i, k]
        elif i >= n_static:
            for k in range(3):
                colour[k] = side_rgb[i - n_static, k]
        else:
            for k in range(3):
                colour[k] = seg_rgb[i, k]
    at = a
    for q in range(ncov + 1):
        gap_hi = c if q == ncov else min(c, cov_lo[q])
        if gap_hi > at:
            if p < 0:
                if n < MAX_PIECES:
                    p_lo[n] = at
                    p_hi[n] = gap_hi
                    for k in range(3):
                        p_rgb[n, k] = colour[k]
                    n += 1
            else:
                g = facade_interval(p, lam * seg_length[i], prof_first, int_s1)
                for r in range(int_first_run[g], int_first_run[g + 1]):
                    r0 = max(at, cam_h + (run_z0[r] - cam_h) * scale)
                    r1 = min(gap_hi, cam_h + (run_z1[r] - cam_h) * scale)
                    if r1 > r0 and n < MAX_PIECES:
                        p_lo[n] = r0
                        p_hi[n] = r1
                        for k in range(3):
                            p_rgb[n, k] = run_rgb[r, k]
                        n += 1
        if q < ncov:
            at = max(at, cov_hi[q])
        if at >= c:
            break
    return n


@numba.njit(cache=True)
def mean_behind(
    lo: float, hi: float, depth: float, p_lo: Array, p_hi: Array, p_rgb: Array, n: int, background: Array,
    focal: float, cy: float, cam_h: float, out: Array,
) -> None:  # fmt: skip
    """The mean colour of the pieces over the heights ``[lo, hi)`` at ``depth``, the sky or the
    ground (the background row at their middle height) where none is."""
    for k in range(3):
        out[k] = 0.0
    if hi <= lo:
        return
    left = hi - lo
    for i in range(n):
        w = min(hi, p_hi[i]) - max(lo, p_lo[i])
        if w <= 0.0:
            continue
        left -= w
        for k in range(3):
            out[k] += w * p_rgb[i, k]
    if left > 1e-12:
        row = int(cy - focal * (0.5 * (lo + hi) - cam_h) / depth)
        row = min(max(row, 0), background.shape[0] - 1)
        for k in range(3):
            out[k] += left * background[row, k]
    for k in range(3):
        out[k] /= hi - lo


@numba.njit(cache=True)
def seen_part(z0: float, z1: float, lo: Array, hi: Array, n: int) -> tuple[float, float]:
    """The length of ``[z0, z1)`` outside the hidden intervals, and a height in its lowest visible stretch."""
    if z1 <= z0:
        return 0.0, 0.0
    total = z1 - z0
    at = z0
    where = -1.0e300
    for i in range(n):
        if hi[i] <= z0 or lo[i] >= z1:
            continue
        if where == -1.0e300 and lo[i] > at:
            where = 0.5 * (at + min(lo[i], z1))
        total -= min(hi[i], z1) - max(lo[i], z0)
        at = max(at, hi[i])
    if where == -1.0e300 and at < z1:
        where = 0.5 * (at + z1)
    return max(total, 0.0), where
