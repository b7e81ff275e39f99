"""The numba kernels of ``far_landmark_pf`` (:mod:`localizers.far_landmark_pf`, paper D): the likelihood of a
detection (eqs. (6)-(13)), the particles' weights under far emphasis (eq. (14)), the lost test's distances and the
re-localization's position votes.

They are the filter's cost (a policy that leaves the route makes the filter search, and every frame
weighs 500 particles against the detections), so each skips work whose result nobody reads, and only that: the
numbers are those of the plain loops, bit for bit (``tests/localizers/test_far_landmark_pf.py`` compares them with
the plain kernels on random frames, and a seeded crowded campus run with its pinned estimates).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


@numba.njit(cache=True)
def _pair_log_likelihood(e_r: float, det_bearing: float, dx: float, dy: float, pth: float, inv_sigma_t: float) -> float:
    """``-0.5 d^2`` of a detection against one landmark at ``(dx, dy)`` from pose heading ``pth``, given
    its inverse range's error ``e_r`` in standard deviations (eqs. (6)-(12))."""
    e_t = det_bearing - (math.atan2(dy, dx) - pth)  # eq. (12), counter-clockwise from the heading
    e_t = ((e_t + math.pi) % (2.0 * math.pi) - math.pi) * inv_sigma_t
    return -0.5 * (e_r * e_r + e_t * e_t)


@numba.njit(cache=True)
def detection_log_likelihood(
    px: float, py: float, pth: float, det_type: int, det_inv_r: float, det_bearing: float,
    lm_xy: Array, type_start: IntArray, inv_sigma_r: float, inv_sigma_t: float,
) -> float:  # fmt: skip
    """Eq. (13): the largest log-likelihood ``-0.5 d^2`` (without the normalizing constant) over
    the same-type map landmarks of a detection seen from pose ``(px, py, pth)``, ``d`` the
    Mahalanobis distance in ``(1/r, theta)``; ``-inf`` without such a landmark."""
    best = -math.inf
    for m in range(type_start[det_type], type_start[det_type + 1]):
        dx = lm_xy[m, 0] - px
        dy = lm_xy[m, 1] - py
        r = math.sqrt(dx * dx + dy * dy)
        if r <= 0.0:
            continue
        ll = _pair_log_likelihood((det_inv_r - 1.0 / r) * inv_sigma_r, det_bearing, dx, dy, pth, inv_sigma_t)
        if ll > best:
            best = ll
    return best


@numba.njit(cache=True)
def _wrap(a: float) -> float:
    """``a`` wrapped into ``[-pi, pi)``."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@numba.njit(cache=True)
def _candidates(
    particles: Array, det_type: IntArray, det_inv_r: Array, det_bearing: Array, order: IntArray, lm_xy: Array,
    type_start: IntArray, gate_inv_r: float, cone: float,
) -> tuple[IntArray, IntArray, IntArray]:  # fmt: skip
    """For each detection ``order[q]``, the same-type landmarks that may match it from some particle:
    ``cand[first[q]:last[q]]``, in the landmarks' order. A landmark is left out when, over the particles' bounding box
    and the span of their headings, its inverse range stays farther than ``gate_inv_r`` from the detection's or its
    bearing farther than ``cone`` (each with a margin far beyond rounding); with a NaN among the particles none is."""
    kk = order.shape[0]
    first = np.zeros(kk + 1, dtype=np.int64)
    for q in range(kk):
        first[q + 1] = first[q] + type_start[det_type[order[q]] + 1] - type_start[det_type[order[q]]]
    cand = np.empty(first[kk], dtype=np.int64)
    last = first[:kk].copy()
    x0, x1 = particles[0].min(), particles[0].max()
    y0, y1 = particles[1].min(), particles[1].max()
    h0, h1 = particles[2].min(), particles[2].max()
    box = math.isfinite(x1 - x0) and math.isfinite(y1 - y0) and math.isfinite(h1 - h0)
    tol = gate_inv_r * (1.0 + 1e-9) + 1e-12
    for q in range(kk):
        k = order[q]
        for m in range(type_start[det_type[k]], type_start[det_type[k] + 1]):
            lx, ly = lm_xy[m, 0], lm_xy[m, 1]
            near_x, near_y = max(x0 - lx, 0.0, lx - x1), max(y0 - ly, 0.0, ly - y1)
            r_min = math.sqrt(near_x * near_x + near_y * near_y)
            far_x, far_y = max(abs(lx - x0), abs(lx - x1)), max(abs(ly - y0), abs(ly - y1))
            r_max = math.sqrt(far_x * far_x + far_y * far_y)
            keep = True
            if box:  # 1/r over the box lies within [1/r_max, 1/r_min]
                inv_lo = (1.0 - 1e-9) / r_max if r_max > 0.0 else math.inf
                inv_hi = (1.0 + 1e-9) / r_min if r_min > 0.0 else math.inf
                keep = inv_hi >= det_inv_r[k] - tol and inv_lo <= det_inv_r[k] + tol
            if box and keep and r_min > 1e-6:  # outside the box: its directions to the landmark lie within those
                ahead = math.atan2(ly - 0.5 * (y0 + y1), lx - 0.5 * (x0 + x1))  # from its corners (the box is convex)
                lo, hi = math.inf, -math.inf
                for cx, cy in ((x0, y0), (x0, y1), (x1, y0), (x1, y1)):
                    d = _wrap(math.atan2(ly - cy, lx - cx) - ahead)
                    lo, hi = min(lo, d), max(hi, d)
                half = 0.5 * (hi - lo) + 0.5 * (h1 - h0) + cone + 1e-6
                keep = half >= math.pi or abs(_wrap(det_bearing[k] - (ahead + 0.5 * (lo + hi) - 0.5 * (h0 + h1)))) <= half
            if keep:
                cand[last[q]] = m
                last[q] += 1
    return cand, first, last


@numba.njit(cache=True)
def particle_log_weights(
    particles: Array, det_type: IntArray, det_inv_r: Array, det_bearing: Array, order: IntArray, starts: IntArray,
    first_only: bool, lm_xy: Array, type_start: IntArray, inv_sigma_r: float, inv_sigma_t: float, log_gate: float,
    log_norm: float, chosen: IntArray,
) -> Array:  # fmt: skip
    """``(N,)`` each particle's log-weight change: the sum, over the groups (sectors), of the
    log-likelihoods of the detections used (eq. (14)): with ``first_only`` the first in each
    group's order that matches (its log-likelihood at least ``log_gate``), else every one that
    matches. ``log_norm``: the Gaussians' log normalizing constant, added per detection used.
    ``chosen`` ``(G,)``, for the last particle: the detection each group used (-1: none).

    The same numbers as :func:`detection_log_likelihood` per detection (bit for bit), with less work: only
    a likelihood at least ``log_gate`` is ever used, so a landmark is skipped as soon as its inverse range
    alone (``-0.5 e_r^2 < log_gate``) or its bearing (outside a cone of the gate's bearing error, plus 1e-6 rad
    for rounding, around the detection's direction: a cross and a dot product) rules that out, before its
    ``atan2``; each landmark's ``1/r`` is computed once per particle (lazily: with ``first_only`` most
    detections are never weighed); and the landmarks that no particle of the set can match by these two tests
    (over the particles' bounding box and span of headings, :func:`_candidates`) are left out before the
    particles' loop. The best of the landmarks left is the same value, and one below the gate is no match either way."""
    n = particles.shape[1]
    out = np.zeros(n)
    groups = starts.shape[0] - 1
    inv_r = np.empty(lm_xy.shape[0])  # this particle's 1/r per landmark (NaN: r is not positive) ...
    filled = np.full(lm_xy.shape[0], -1, dtype=np.int64)  # ... filled for particle filled[m]
    cone = math.sqrt(-2.0 * log_gate) / inv_sigma_t + 1e-6  # beyond this bearing error no landmark matches
    use_cone = cone < 0.25 * math.pi
    sin_cone = math.sin(cone)
    cand, first, last = _candidates(particles, det_type, det_inv_r, det_bearing, order, lm_xy, type_start,
                                    math.sqrt(-2.0 * log_gate) / inv_sigma_r, cone)  # fmt: skip
    cos_b = np.cos(det_bearing)
    sin_b = np.sin(det_bearing)
    for i in range(n):
        px = particles[0, i]
        py = particles[1, i]
        pth = particles[2, i]
        cos_h = math.cos(pth)
        sin_h = math.sin(pth)
        total = 0.0
        for g in range(groups):
            if i == n - 1:
                chosen[g] = -1
            for q in range(starts[g], starts[g + 1]):
                k = order[q]
                ux = cos_h * cos_b[k] - sin_h * sin_b[k]  # the detection's direction in the world
                uy = sin_h * cos_b[k] + cos_h * sin_b[k]
                best = -math.inf
                for c in range(first[q], last[q]):
                    m = cand[c]
                    dx = lm_xy[m, 0] - px
                    dy = lm_xy[m, 1] - py
                    if filled[m] != i:
                        filled[m] = i
                        r = math.sqrt(dx * dx + dy * dy)
                        inv_r[m] = 1.0 / r if r > 0.0 else math.nan
                    if math.isnan(inv_r[m]):
                        continue
                    e_r = (det_inv_r[k] - inv_r[m]) * inv_sigma_r
                    if -0.5 * (e_r * e_r) < log_gate:
                        continue
                    if use_cone and (ux * dx + uy * dy <= 0.0 or abs(ux * dy - uy * dx) * inv_r[m] > sin_cone):
                        continue
                    ll = _pair_log_likelihood(e_r, det_bearing[k], dx, dy, pth, inv_sigma_t)
                    if ll > best:
                        best = ll
                if best >= log_gate:
                    total += best + log_norm
                    if i == n - 1:
                        chosen[g] = k
                    if first_only:
                        break
        out[i] = total
    return out


@numba.njit(cache=True)
def detection_distances(
    px: float, py: float, pth: float, det_type: IntArray, det_inv_r: Array, det_bearing: Array, order: IntArray,
    lm_xy: Array, type_start: IntArray, inv_sigma_r: float, inv_sigma_t: float, cover_rad: float,
) -> Array:  # fmt: skip
    """``(K,)`` for the detections ``order``, seen from pose ``(px, py, pth)``: the Mahalanobis distance
    (in ``(1/r, theta)``) to the nearest same-type landmark (eq. (13)'s best; inf without one); NaN for a
    detection with no landmark of any type within ``cover_rad`` of its bearing (a direction the mapping
    drive never looked in, which says nothing about the pose). Each landmark's bearing from the pose is computed
    once, not once per detection."""
    out = np.empty(order.shape[0])
    seen_at = np.empty(lm_xy.shape[0])  # each landmark's atan2 - pth, the same for every detection
    for m in range(lm_xy.shape[0]):
        seen_at[m] = math.atan2(lm_xy[m, 1] - py, lm_xy[m, 0] - px) - pth
    for q in range(order.shape[0]):
        k = order[q]
        covered = False
        for m in range(lm_xy.shape[0]):
            e = det_bearing[k] - seen_at[m]
            if abs((e + math.pi) % (2.0 * math.pi) - math.pi) <= cover_rad:
                covered = True
                break
        if not covered:
            out[q] = math.nan
            continue
        ll = detection_log_likelihood(px, py, pth, det_type[k], det_inv_r[k], det_bearing[k], lm_xy, type_start,
                                      inv_sigma_r, inv_sigma_t)  # fmt: skip
        out[q] = math.sqrt(-2.0 * ll) if ll > -math.inf else math.inf
    return out


@numba.njit(cache=True)
def _ray_in_band(offset: float, u: float, width: float, margin: float) -> tuple[float, float]:
    """The ``rho`` for which ``offset - rho u`` lies within ``[-margin, width + margin]`` (empty: ``lo > hi``)."""
    if u > 0.0:
        return (offset - width - margin) / u, (offset + margin) / u
    if u < 0.0:
        return (offset + margin) / u, (offset - width - margin) / u
    return (-math.inf, math.inf) if -margin <= offset <= width + margin else (math.inf, -math.inf)


@numba.njit(cache=True)
def position_votes(
    cx: float, cy: float, headings: Array, half_cells: int, cell_m: float, det_type: IntArray, det_inv_r: Array,
    det_bearing: Array, order: IntArray, lm_xy: Array, type_start: IntArray, inv_r_gate: float,
) -> IntArray:  # fmt: skip
    """Hough votes for the robot's position, ``(H, 2 half_cells + 1, 2 half_cells + 1)``: at heading ``headings[h]``,
    a detection ``(1/r, theta)`` of a landmark at ``l`` puts the robot on the ray ``l - rho (cos, sin)(theta + heading)``
    with ``1/rho`` within ``inv_r_gate`` of ``1/r``; each detection votes once for every cell (of ``cell_m``, the grid
    centred on ``(cx, cy)``) one of its same-type landmarks puts the robot in. A cell's votes: how many detections
    it explains.

    ``rho`` walks the ray in steps of half a cell from where it may come within ``1.5 (half_cells + 1)`` cells of the
    centre; the steps outside the grid (widened by a cell against rounding: the ray's slab intersection) only advance
    ``rho``, by the same additions, and a ray that misses the grid takes none: the same cells, fewer operations."""
    n = 2 * half_cells + 1
    ox = cx - (half_cells + 0.5) * cell_m
    oy = cy - (half_cells + 0.5) * cell_m
    reach = (half_cells + 1) * cell_m * 1.5
    width = n * cell_m
    dist = np.empty(lm_xy.shape[0])  # each landmark's distance from the centre, at every heading and detection
    for m in range(lm_xy.shape[0]):
        dist[m] = math.hypot(lm_xy[m, 0] - cx, lm_xy[m, 1] - cy)
    votes = np.zeros((headings.shape[0], n, n), dtype=np.int64)
    stamp = np.empty((n, n), dtype=np.int64)
    for h in range(headings.shape[0]):
        stamp[:, :] = -1
        for q in range(order.shape[0]):
            k = order[q]
            inv = det_inv_r[k]
            rho_lo = 1.0 / (inv + inv_r_gate)
            rho_hi = 1.0 / (inv - inv_r_gate) if inv > inv_r_gate else 1e9
            a = det_bearing[k] + headings[h]
            ux = math.cos(a)
            uy = math.sin(a)
            t = det_type[k]
            for m in range(type_start[t], type_start[t + 1]):
                lx = lm_xy[m, 0]
                ly = lm_xy[m, 1]
                rho = max(rho_lo, dist[m] - reach)
                hi = min(rho_hi, dist[m] + reach)
                x_lo, x_hi = _ray_in_band(lx - ox, ux, width, cell_m)
                y_lo, y_hi = _ray_in_band(ly - oy, uy, width, cell_m)
                enter = max(x_lo, y_lo)
                hi_in = min(hi, x_hi, y_hi)
                if max(rho, enter) > hi_in:
                    continue  # no step of this ray lands in the grid
                while rho < enter:
                    rho += 0.5 * cell_m
                while rho <= hi_in:
                    i = int(math.floor((lx - rho * ux - ox) / cell_m))
                    j = int(math.floor((ly - rho * uy - oy) / cell_m))
                    if 0 <= i < n and 0 <= j < n and stamp[i, j] != q:
                        stamp[i, j] = q
                        votes[h, i, j] += 1
                    rho += 0.5 * cell_m
    return votes


@numba.njit(cache=True)
def top_cells(votes: IntArray, k: int) -> IntArray:
    """The flat indices of the ``k`` largest of ``votes`` (any shape), largest first, a tie going to the later index:
    ``np.argsort(votes, axis=None, kind="stable")[::-1][:k]`` in one pass instead of a sort (the search's vote grid at the
    defaults: 51 headings of 33 x 33 cells, of which it refines three; the sort took 1.2 ms of a 7 ms search)."""
    flat = votes.ravel()
    k = max(0, min(k, flat.size))
    best_v = np.empty(k, dtype=votes.dtype)
    best_i = np.empty(k, dtype=np.int64)
    held = 0
    for idx in range(flat.size if k else 0):
        v = flat[idx]
        if held == k and v < best_v[k - 1]:
            continue
        p = 0  # ahead of every held value it equals: the later index ranks first among equals
        while p < held and best_v[p] > v:
            p += 1
        last = min(held, k - 1)
        for q in range(last, p, -1):
            best_v[q] = best_v[q - 1]
            best_i[q] = best_i[q - 1]
        best_v[p] = v
        best_i[p] = idx
        held = min(held + 1, k)
    return best_i
