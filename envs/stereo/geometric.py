"""The fast mode: the edges the image mode would detect, computed from the world's geometry.

Instead of rendering three images and filtering them, the fast mode lists the vertical lines
of the world where a colour changes as the middle camera sees it, and gives each the filter
response the image mode's tall filter would measure at each detection row:

- *façade breaks*: the vertical edges inside the façades (windows, panels, pilasters, doors:
  :class:`envs.stereo.scene.StaticScene`'s breaks), on the sides that face the camera;
- *corners and silhouettes* of every convex object (buildings, poles, trunks, crowns, the
  box parts of cars): a corner where two sides facing the camera meet (their colours differ
  by their shading), a silhouette where a side facing the camera meets one facing away (the
  object's colour against whatever the line of sight meets behind it, or the sky or the
  ground);
- the two *silhouettes* of every disc part (people's legs, torsos, heads) against what is behind.

For each line and detection row, the response per channel is the sum, over the line's height
runs, of the share of the filter window's rows the run covers at the line's depth times the
colour step across it (right minus left): exactly what the image filter gives for a sharp edge
with uniform colours either side. The line counts at a row only if its line of sight (through
the middle of the covered part) is clear up to it; a silhouette's background is what that
line of sight meets beyond it. An object narrower in the image than half the filter's width
(a far pole) gives a proportionally weaker response, as it does in the images.

Approximations (documented, measured against the image mode in the tests): occlusion and the
background are taken on one line of sight per row rather than over the window; the colours of
a corner or silhouette are taken at that line's height; lines closer together than half the
filter's width are not mixed (the weaker of two of a type is dropped, :func:`camera_edges`).
The rows model (:func:`row_response`, the sensor's ``fast_edges: rows``) removes the last: it rebuilds
each camera's filter response along each row from all the lines' steps and finds the peaks there.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from envs.stereo.render import NEAR_M
from envs.stereo.scene import facade_interval
from envs.stereo.sight import MAX_BLOCKERS, MAX_PIECES, blockers, column_behind, entries, mean_behind, seen_part

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


@numba.njit(cache=True, inline="always")
def _facade(p: int, s: float, z: float, prof_first: IntArray, int_s1: Array, int_first_run: IntArray, run_z1: Array,
            run_rgb: Array, out: Array) -> None:  # fmt: skip
    """The colour of façade profile ``p`` at ``(s, z)`` into ``out`` (3,)."""
    g = facade_interval(p, s, prof_first, int_s1)
    j = int_first_run[g]
    last = int_first_run[g + 1] - 1
    while j < last and z >= run_z1[j]:
        j += 1
    for c in range(3):
        out[c] = run_rgb[j, c]


@numba.njit(cache=True, inline="always")
def seg_profile_of(s: int, n_static: int, seg_profile: IntArray) -> int:
    """Segment ``s``'s façade profile, -1 for a flat one (a moving box's side is flat)."""
    return seg_profile[s] if s < n_static else -1


@numba.njit(cache=True, inline="always")
def _flat_rgb(s: int, n_static: int, seg_rgb: Array, side_rgb: Array, c: int) -> float:
    """Channel ``c`` of flat segment ``s``'s colour (a static one's or a moving box side's)."""
    return seg_rgb[s, c] if s < n_static else side_rgb[s - n_static, c]


@numba.njit(cache=True)
def _best_share(z0: float, z1: float, depth: float, rows: IntArray, half: int, focal: float, cy: float, cam_h: float) -> float:
    """The largest share of a detection row's filter window that the heights ``[z0, z1)`` at
    ``depth`` cover (unoccluded): an upper bound of the response per unit of colour step."""
    best = 0.0
    for lv in range(rows.shape[0]):
        bottom, top = _window(depth, rows[lv], half, focal, cy, cam_h)
        best = max(best, (min(z1, top) - max(z0, bottom)) / (top - bottom))
    return best


@numba.njit(cache=True, inline="always")
def _window(depth: float, row: int, half: int, focal: float, cy: float, cam_h: float) -> tuple[float, float]:
    """The heights at ``depth`` the filter window (rows ``row - half`` to ``row + half``) spans: ``(bottom, top)``."""
    return cam_h + (cy - (row + half + 1)) * depth / focal, cam_h + (cy - (row - half)) * depth / focal


@numba.njit(cache=True)
def lines(
    cam: Array, fwd: Array, focal: float, cx: float, cy: float, width: int, cam_h: float, max_range: float,
    rows: IntArray, half: int, margin_px: float, min_response: float, narrow_px: float, weaken: bool,
    seg_a: Array, seg_b: Array, seg_z0: Array, seg_z1: Array, cull: NDArray[np.bool_], n_static: int,
    seg_profile: IntArray, seg_length: Array, seg_rgb: Array, side_rgb: Array,
    obj_first: IntArray, obj_count: IntArray, obj_z0: Array, obj_z1: Array,
    seg_first_brk: IntArray, brk_xy: Array, brk_first_run: IntArray, brun_z0: Array, brun_z1: Array,
    brun_left: Array, brun_right: Array,
    disc_xy: Array, disc_r: Array, disc_z0: Array, disc_z1: Array, disc_rgb: Array,
    prof_first: IntArray, int_s1: Array, int_first_run: IntArray, run_z0: Array, run_z1: Array, run_rgb: Array,
    background: Array,
) -> tuple[Array, Array, IntArray, Array]:  # fmt: skip
    """Every vertical colour line the middle camera sees, with its response at each detection row.

    ``seg_*`` hold the static segments followed by the moving box sides (``n_static`` static
    ones); objects (convex solids, then the boxes) are runs of consecutive segments.

    Returns:
        ``X``, ``Z`` ``(N,)``: each line's point in the middle camera's (right, forward) frame;
        ``level`` ``(N,)``: the detection row; ``response`` ``(N, 3)``: the filter's response per
        channel (right minus left, at unit gain), counting only the window's rows where the line
        is in sight. Only lines whose largest response reaches ``min_response`` are kept. ``weaken``: a
        line narrower in the image than ``narrow_px``, or closer to its neighbours, responds weaker (the lines
        model); without it (the rows model, whose filter mixes neighbours itself) it keeps its full step, and
        the narrowness of an object only bounds which of its silhouettes can count (its two cancel beyond it).
    """
    geom, kind, ref, first, members = entries(cam, fwd, focal, cx, width, max_range, seg_a, seg_b, seg_z0, seg_z1, cull,
                                               disc_xy, disc_r, disc_z0, disc_z1)  # fmt: skip
    fx, fy = fwd[0], fwd[1]
    rx, ry = fy, -fx
    levels = rows.shape[0]
    cap = 8192
    out_x = np.empty(cap)
    out_z = np.empty(cap)
    out_l = np.empty(cap, dtype=np.int64)
    out_r = np.empty((cap, 3))
    n = 0
    left = np.empty(3)
    right = np.empty(3)
    resp = np.empty(3)
    blo = np.empty(MAX_BLOCKERS)
    bhi = np.empty(MAX_BLOCKERS)
    p_lo = np.empty(MAX_PIECES)
    p_hi = np.empty(MAX_PIECES)
    p_rgb = np.empty((MAX_PIECES, 3))
    scratch = np.empty((5, 32))
    scratch_e = np.empty(32, dtype=np.int64)
    cols = np.empty(256)
    u_lo = margin_px
    u_hi = width - margin_px
    # ---- façade breaks, side by side
    for i in range(n_static):
        lo_b = seg_first_brk[i]
        hi_b = seg_first_brk[i + 1]
        if hi_b == lo_b:
            continue
        ax = seg_a[i, 0] - cam[0]
        ay = seg_a[i, 1] - cam[1]
        bx = seg_b[i, 0] - cam[0]
        by = seg_b[i, 1] - cam[1]
        if -ax * (by - ay) + ay * (bx - ax) <= 0.0:
            continue  # seen from inside its solid: a back face
        # the breaks' columns, with the side's ends around them: a break closer in the image to
        # its neighbours than half the filter's width is blurred into them (a façade seen edge-on)
        if hi_b - lo_b + 2 > cols.shape[0]:
            cols = np.empty(hi_b - lo_b + 2)
        for q in range(hi_b - lo_b + 2):
            if q == 0:
                qx, qy = ax, ay
            elif q == hi_b - lo_b + 1:
                qx, qy = bx, by
            else:
                qx = brk_xy[lo_b + q - 1, 0] - cam[0]
                qy = brk_xy[lo_b + q - 1, 1] - cam[1]
            qz = qx * fx + qy * fy
            cols[q] = cx + focal * (qx * rx + qy * ry) / qz if qz > NEAR_M else np.nan
        for k in range(lo_b, hi_b):
            px = brk_xy[k, 0] - cam[0]
            py = brk_xy[k, 1] - cam[1]
            z = px * fx + py * fy
            if z < NEAR_M or z > max_range:
                continue
            x = px * rx + py * ry
            u = cx + focal * x / z
            if u < u_lo or u >= u_hi:
                continue
            q = k - lo_b + 1
            gap = min(abs(cols[q] - cols[q - 1]), abs(cols[q + 1] - cols[q]))  # NaN (an end behind): no limit
            crowd = min(1.0, gap / narrow_px) if gap == gap else 1.0
            # the response it would have in clear view bounds what it can have: below the least, skip it
            bound = 0.0
            for lv in range(levels):
                bottom, top = _window(z, rows[lv], half, focal, cy, cam_h)
                acc = 0.0
                for j in range(brk_first_run[k], brk_first_run[k + 1]):
                    cover = min(brun_z1[j], top) - max(brun_z0[j], bottom)
                    if cover > 0.0:
                        step = max(abs(brun_right[j, 0] - brun_left[j, 0]), abs(brun_right[j, 1] - brun_left[j, 1]),
                                   abs(brun_right[j, 2] - brun_left[j, 2]))  # fmt: skip
                        acc += cover / (top - bottom) * step
                bound = max(bound, (crowd if weaken else 1.0) * acc)  # (the rows model's filter adds close steps)
            if bound < min_response:
                continue
            nb = blockers(u, z, cam_h, focal, cx, geom, kind, first, members, blo, bhi)
            for lv in range(levels):
                bottom, top = _window(z, rows[lv], half, focal, cy, cam_h)
                for c in range(3):
                    resp[c] = 0.0
                for j in range(brk_first_run[k], brk_first_run[k + 1]):
                    seen, _ = seen_part(max(brun_z0[j], bottom), min(brun_z1[j], top), blo, bhi, nb)
                    if seen <= 0.0:
                        continue
                    share = (crowd if weaken else 1.0) * seen / (top - bottom)
                    for c in range(3):
                        resp[c] += share * (brun_right[j, c] - brun_left[j, c])
                if max(abs(resp[0]), abs(resp[1]), abs(resp[2])) < min_response or n >= cap:
                    continue
                out_x[n] = x
                out_z[n] = z
                out_l[n] = lv
                for c in range(3):
                    out_r[n, c] = resp[c]
                n += 1
    # ---- corners and silhouettes of the objects (static solids, then the boxes)
    for o in range(obj_first.shape[0]):
        f0 = obj_first[o]
        cnt = obj_count[o]
        # the object's extent in the image: narrow objects respond weakly
        u_min = 1e300
        u_max = -1e300
        cut = False
        for q in range(cnt):
            s = f0 + q
            px = seg_a[s, 0] - cam[0]
            py = seg_a[s, 1] - cam[1]
            z = px * fx + py * fy
            if z < NEAR_M:
                cut = True
                break
            uu = cx + focal * (px * rx + py * ry) / z
            u_min = min(u_min, uu)
            u_max = max(u_max, uu)
        narrow = 1.0 if cut else min(1.0, (u_max - u_min) / narrow_px)
        for q in range(cnt):
            s = f0 + q
            prev = f0 + (q - 1 + cnt) % cnt
            ax = seg_a[s, 0] - cam[0]
            ay = seg_a[s, 1] - cam[1]
            bx = seg_b[s, 0] - cam[0]
            by = seg_b[s, 1] - cam[1]
            front = -ax * (by - ay) + ay * (bx - ax) > 0.0
            pax = seg_a[prev, 0] - cam[0]
            pay = seg_a[prev, 1] - cam[1]
            front_prev = -pax * (ay - pay) + pay * (ax - pax) > 0.0  # the previous side ends at this corner
            if not front and not front_prev:
                continue
            z = ax * fx + ay * fy
            if z < NEAR_M or z > max_range:
                continue
            x = ax * rx + ay * ry
            u = cx + focal * x / z
            if u < u_lo or u >= u_hi:
                continue
            corner = front and front_prev
            if corner and seg_profile_of(prev, n_static, seg_profile) < 0 and seg_profile_of(s, n_static, seg_profile) < 0:
                # two flat sides: one colour (a pole's, a crown's, a car's box: no shading), no edge
                same = True
                for c in range(3):
                    same = same and _flat_rgb(prev, n_static, seg_rgb, side_rgb, c) == _flat_rgb(
                        s, n_static, seg_rgb, side_rgb, c
                    )
                if same:
                    continue
            weight = 1.0 if corner else narrow
            if weight * 255.0 * _best_share(obj_z0[o], obj_z1[o], z, rows, half, focal, cy, cam_h) < min_response:
                continue  # too little of it in any window for even a black-white step to count
            pieces = 0
            if corner:
                nb = blockers(u, z, cam_h, focal, cx, geom, kind, first, members, blo, bhi)
            else:  # a silhouette: also what lies behind on the open side
                nb, pieces = column_behind(u, z, max_range, cam_h, focal, cx, geom, kind, ref, first, members, n_static, seg_profile,
                                     seg_length, seg_rgb, side_rgb, disc_rgb, prof_first, int_s1, int_first_run, run_z0, run_z1,
                                     run_rgb, blo, bhi, p_lo, p_hi, p_rgb, scratch, scratch_e, obj_z0[o], obj_z1[o])  # fmt: skip
            for lv in range(levels):
                bottom, top = _window(z, rows[lv], half, focal, cy, cam_h)
                span_lo, span_hi = max(obj_z0[o], bottom), min(obj_z1[o], top)
                seen, mid = seen_part(span_lo, span_hi, blo, bhi, nb)
                if seen <= 0.0:
                    continue
                if front_prev:  # the side ending here: its colour at its end
                    _side_colour(prev, seg_length[prev], mid, n_static, seg_profile, seg_rgb, side_rgb, prof_first, int_s1,
                                 int_first_run, run_z1, run_rgb, left)  # fmt: skip
                if front:
                    _side_colour(s, 0.0, mid, n_static, seg_profile, seg_rgb, side_rgb, prof_first, int_s1, int_first_run,
                                 run_z1, run_rgb, right)  # fmt: skip
                if not corner:
                    mean_behind(span_lo, span_hi, z, p_lo, p_hi, p_rgb, pieces, background, focal, cy, cam_h,
                                 right if front_prev else left)  # fmt: skip
                share = (weight if weaken else 1.0) * seen / (top - bottom)
                for c in range(3):
                    resp[c] = share * (right[c] - left[c])
                if max(abs(resp[0]), abs(resp[1]), abs(resp[2])) < min_response or n >= cap:
                    continue
                out_x[n] = x
                out_z[n] = z
                out_l[n] = lv
                for c in range(3):
                    out_r[n, c] = resp[c]
                n += 1
    # ---- the silhouettes of the discs
    for i in range(disc_xy.shape[0]):
        px = disc_xy[i, 0] - cam[0]
        py = disc_xy[i, 1] - cam[1]
        xc = px * rx + py * ry
        zc = px * fx + py * fy
        r = disc_r[i]
        if zc - r < NEAR_M or zc > max_range:
            continue
        u_c = cx + focal * xc / zc
        reach = focal * r / (zc - r)  # more than the silhouette's half width in the image
        if u_c + reach < u_lo or u_c - reach >= u_hi:
            continue  # out of view
        if narrow_px * min_response > 255.0 * 2.0 * reach:
            continue  # too narrow for even a black-white step to count
        d2 = xc * xc + zc * zc
        dist = math.sqrt(d2)
        tangent = math.sqrt(d2 - r * r)
        narrow = min(1.0, 2.0 * focal * r / zc / narrow_px)
        for side in (-1.0, 1.0):  # -1: the left silhouette (smaller u), +1: the right one
            # the tangent point: turn the direction to the centre by asin(r / dist) toward the side
            ang = math.atan2(xc, zc) + side * math.asin(r / dist)
            x = tangent * math.sin(ang)
            z = tangent * math.cos(ang)
            if z < NEAR_M:
                continue
            u = cx + focal * x / z
            if u < u_lo or u >= u_hi:
                continue
            if narrow * 255.0 * _best_share(disc_z0[i], disc_z1[i], z, rows, half, focal, cy, cam_h) < min_response:
                continue  # too little of it in any window for even a black-white step to count
            nb, pieces = column_behind(u, z, max_range, cam_h, focal, cx, geom, kind, ref, first, members, n_static, seg_profile,
                                 seg_length, seg_rgb, side_rgb, disc_rgb, prof_first, int_s1, int_first_run, run_z0, run_z1,
                                 run_rgb, blo, bhi, p_lo, p_hi, p_rgb, scratch, scratch_e, disc_z0[i], disc_z1[i])  # fmt: skip
            for lv in range(levels):
                bottom, top = _window(z, rows[lv], half, focal, cy, cam_h)
                span_lo, span_hi = max(disc_z0[i], bottom), min(disc_z1[i], top)
                seen, _ = seen_part(span_lo, span_hi, blo, bhi, nb)
                if seen <= 0.0:
                    continue
                mean_behind(span_lo, span_hi, z, p_lo, p_hi, p_rgb, pieces, background, focal, cy, cam_h,
                             left if side < 0 else right)  # fmt: skip
                body = right if side < 0 else left
                for c in range(3):
                    body[c] = disc_rgb[i, c]
                share = (narrow if weaken else 1.0) * seen / (top - bottom)
                for c in range(3):
                    resp[c] = share * (right[c] - left[c])
                if max(abs(resp[0]), abs(resp[1]), abs(resp[2])) < min_response or n >= cap:
                    continue
                out_x[n] = x
                out_z[n] = z
                out_l[n] = lv
                for c in range(3):
                    out_r[n, c] = resp[c]
                n += 1
    return out_x[:n].copy(), out_z[:n].copy(), out_l[:n].copy(), out_r[:n].copy()


@numba.njit(cache=True)
def _side_colour(
    s: int, along: float, z: float, n_static: int, seg_profile: IntArray, seg_rgb: Array, side_rgb: Array,
    prof_first: IntArray, int_s1: Array, int_first_run: IntArray, run_z1: Array, run_rgb: Array, out: Array,
) -> None:  # fmt: skip
    """The colour of segment ``s`` at ``along`` metres from its first end and height ``z``."""
    if s >= n_static:
        for c in range(3):
            out[c] = side_rgb[s - n_static, c]
        return
    p = seg_profile[s]
    if p < 0:
        for c in range(3):
            out[c] = seg_rgb[s, c]
        return
    _facade(p, along, z, prof_first, int_s1, int_first_run, run_z1, run_rgb, out)


@numba.njit(cache=True)
def camera_edges(
    x: Array, z: Array, types: IntArray, strength: NDArray[np.float32], lateral: float, focal: float, cx: float,
    width: int, margin_px: float, noise: Array, within_px: float,
) -> tuple[Array, IntArray, NDArray[np.float32]]:  # fmt: skip
    """One camera's edge list from the lines' edges: each edge's column in the camera ``lateral``
    metres left of the middle one (``u = cx + f (X + lateral) / Z``) plus its ``noise`` (px),
    those at least ``margin_px`` inside the image, sorted by ``(type, u)``; of two of one type
    closer than ``within_px`` (at the pixel boundaries they fall on) the weaker is dropped: the
    image filter makes one peak of two steps of one sign that close."""
    n = x.shape[0]
    u = np.empty(n)
    key = np.empty(n)
    keep = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        u[i] = cx + focal * (x[i] + lateral) / z[i] + noise[i]
        keep[i] = margin_px <= u[i] < width - margin_px
        key[i] = types[i] * 1e6 + u[i]
    order = np.argsort(key)
    out_u = np.empty(n)
    out_t = np.empty(n, dtype=np.int64)
    out_s = np.empty(n, dtype=np.float32)
    m = 0
    for q in range(n):
        i = order[q]
        if not keep[i]:
            continue
        # (compared at the pixel boundaries a sharp image puts them on: round(u))
        if m > 0 and out_t[m - 1] == types[i] and round(u[i]) - round(out_u[m - 1]) < within_px:
            if strength[i] > out_s[m - 1]:  # the stronger of the two stays
                out_u[m - 1] = u[i]
                out_s[m - 1] = strength[i]
            continue
        out_u[m] = u[i]
        out_t[m] = types[i]
        out_s[m] = strength[i]
        m += 1
    return out_u[:m].copy(), out_t[:m].copy(), out_s[:m].copy()


@numba.njit(cache=True)
def row_response(
    u: Array, level: IntArray, response: Array, gains: Array, width: int, levels: int, half: int
) -> NDArray[np.float32]:  # fmt: skip
    """One camera's filter response along each detection row, rebuilt from the lines' colour steps: what
    :func:`envs.stereo.edges.vertical_edge_response` gives on an image whose only changes along a row
    are these steps (the fast mode's ``fast_edges: rows``).

    Line ``n`` at column ``u[n]`` (continuous) is a step of ``gains * response[n]`` (right minus left, per
    channel, the window's share included) at the pixel boundary ``b = ceil(u - 0.5)``, where a renderer
    sampling pixel centres puts it. The filter (the mean of the ``half`` columns right of column ``k`` minus
    that of the ``half`` left of it) answers a unit step at ``b`` with
    ``(clamp(k + half - b + 1, 0, half) - clamp(k - b, 0, half)) / half``: 1 at ``k = b - 1`` and ``b``,
    falling to 0 ``half`` columns either side. Steps closer than the filter's width add up or cancel, as in
    the image. Columns within ``half`` of the border get 0, as in the image.

    Returns:
        ``(levels, width, 3)`` float32.
    """
    out = np.zeros((levels, width, 3))
    for n in range(u.shape[0]):
        b = int(math.ceil(u[n] - 0.5))
        lv = level[n]
        for k in range(max(half, b - half), min(width - half, b + half)):
            w = (min(max(k + half - b + 1, 0), half) - min(max(k - b, 0), half)) / half
            for c in range(3):
                out[lv, k, c] += w * gains[c] * response[n, c]
    return out.astype(np.float32)
