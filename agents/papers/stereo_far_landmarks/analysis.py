"""Statistics of the runs and the verdicts on the paper's claims, as data (the words are :mod:`.report`'s).

Two yardsticks: the simulator's true pose (errors, failures, availability) and the LIDAR
reference's estimate (the paper's Fig. 10: the distance between far_landmark_pf's estimate
and amcl's). A *failure* is an estimate at least ``FAIL_M`` from the truth, *lost* a step
without a claimed pose. Paired comparisons are per seed (the same run 2 replayed into both
localizers) with a percentile-bootstrap interval of the mean difference
(:func:`agents.evaluate.stats.bootstrap_ci`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from agents.evaluate import consistency, metrics
from agents.evaluate.stats import bootstrap_ci

from . import paper, world
from .experiment import (
    ABOUT,
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    CORRECTION_S,
    FAIL_M,
    FAILING_SHARE,
    KEYS,
    PAPER_SELECTION,
    REFERENCE_KEY,
    SMOOTH_S,
    SPARSE_USED,
    SPARSE_WINDOW_S,
    Plan,
)
from .jobs import Episode, MapResult

Array = NDArray[np.float64]
Outcome = Literal["holds", "partly holds", "does not hold", "not testable here"]

# ------------------------------------------------------------------------------------ per run


def errors_m(ep: Episode, key: str) -> Array:
    """``(T,)`` position errors of a localizer against the truth (NaN where it claimed no pose)."""
    return metrics.position_errors(ep.estimates[key], ep.truth)


def heading_errors_deg(ep: Episode, key: str) -> Array:
    return np.degrees(metrics.heading_errors(ep.estimates[key], ep.truth))


def difference_m(ep: Episode, key: str) -> Array:
    """``(T,)`` the distance between a localizer's estimate and the LIDAR reference's (Fig. 10)."""
    return metrics.position_errors(ep.estimates[key], ep.estimates[REFERENCE_KEY])


def _finite(v: Array) -> Array:
    return v[np.isfinite(v)]


@dataclass(frozen=True)
class RunStats:
    """One localizer on one run 2.

    Attributes:
        key, seed, crowd_size: which.
        steps: steps of the run.
        mean_m, median_m, p95_m, max_m: position error against the truth over the steps with a pose.
        heading_mean_deg, heading_max_deg: absolute heading error.
        failure_share: steps with a pose >= ``FAIL_M`` off, over all steps.
        lost_share: steps without a pose, over all steps (availability is 1 - it).
        diff_mean_m, diff_max_m: the distance to the reference's estimate (NaN for the reference).
    """

    key: str
    seed: int
    crowd_size: int
    steps: int
    mean_m: float
    median_m: float
    p95_m: float
    max_m: float
    heading_mean_deg: float
    heading_max_deg: float
    failure_share: float
    lost_share: float
    diff_mean_m: float
    diff_max_m: float

    @property
    def bad_share(self) -> float:
        """Failures and lost steps together."""
        return self.failure_share + self.lost_share


def run_stats(ep: Episode, key: str) -> RunStats:
    err = errors_m(ep, key)
    e = _finite(err)
    h = _finite(heading_errors_deg(ep, key))
    valid = np.isfinite(err)
    nan = math.nan
    d = _finite(difference_m(ep, key)) if key != REFERENCE_KEY else np.zeros(0)
    return RunStats(
        key, ep.seed, ep.crowd_size, ep.steps,
        float(e.mean()) if e.size else nan, float(np.median(e)) if e.size else nan,
        float(np.percentile(e, 95)) if e.size else nan, float(e.max()) if e.size else nan,
        float(h.mean()) if h.size else nan, float(h.max()) if h.size else nan,
        float(np.count_nonzero(valid & (np.nan_to_num(err) >= FAIL_M)) / ep.steps), float(1.0 - valid.mean()),
        float(d.mean()) if d.size else nan, float(d.max()) if d.size else nan,
    )  # fmt: skip


def all_run_stats(episodes: Sequence[Episode]) -> list[RunStats]:
    return [run_stats(ep, key) for ep in episodes for key in KEYS]


def track_errors_m(episodes: Sequence[Episode], key: str) -> tuple[float, float]:
    """Mean absolute error along the true heading and across it, over every step with a pose of the runs."""
    along, cross = [], []
    for ep in episodes:
        d = ep.estimates[key][:, :2] - ep.truth[:, :2]
        c, s = np.cos(ep.truth[:, 2]), np.sin(ep.truth[:, 2])
        along.append(np.abs(d[:, 0] * c + d[:, 1] * s))
        cross.append(np.abs(-d[:, 0] * s + d[:, 1] * c))
    a, x = _finite(np.concatenate(along)), _finite(np.concatenate(cross))
    return (float(a.mean()) if a.size else math.nan, float(x.mean()) if x.size else math.nan)


# ------------------------------------------------------------------------------------ per localizer and crowd size


@dataclass(frozen=True)
class Summary:
    """One localizer at one crowd size over the seeds.

    Attributes:
        runs: runs (seeds).
        mean_m: mean of the per-run mean errors; ``seed_sd_m``: their sd over the seeds.
        median_m, p95_m, max_m: over every step with a pose of every run.
        failure_share, lost_share: over every step of every run; ``availability`` = 1 - lost.
        runs_failing: runs with at least one failure or lost step.
        diff_max_m: the largest distance to the reference over the runs; ``diff_run_max_m``: the
            per-run maxima (seed order); ``diff_mean_m``: the mean distance.
        nees_median, inside_95: the consistency of the reported covariance over every step with a
            pose of every run (:func:`agents.evaluate.consistency.pooled`); ``covariance_missing``: the
            share of those steps without a usable covariance (left out of both).
    """

    key: str
    crowd_size: int
    runs: int
    mean_m: float
    seed_sd_m: float
    median_m: float
    p95_m: float
    max_m: float
    heading_mean_deg: float
    failure_share: float
    lost_share: float
    availability: float
    runs_failing: int
    diff_mean_m: float
    diff_max_m: float
    diff_run_max_m: tuple[float, ...]
    nees_median: float = math.nan
    inside_95: float = math.nan
    covariance_missing: float = math.nan

    @property
    def bad_share(self) -> float:
        return self.failure_share + self.lost_share

    @property
    def fails(self) -> bool:
        """At least ``FAILING_SHARE`` of the steps are failures or lost."""
        return self.bad_share >= FAILING_SHARE


def summarize(episodes: Sequence[Episode], key: str) -> Summary:
    """Raises ValueError without episodes."""
    if not episodes:
        raise ValueError("summarize: no episodes")
    eps = sorted(episodes, key=lambda e: e.seed)
    rs = [run_stats(ep, key) for ep in eps]
    err = np.concatenate([_finite(errors_m(ep, key)) for ep in eps])
    head = np.concatenate([_finite(heading_errors_deg(ep, key)) for ep in eps])
    steps = sum(r.steps for r in rs)
    spread = metrics.over_seeds([r.mean_m for r in rs])
    diffs = [_finite(difference_m(ep, key)) for ep in eps] if key != REFERENCE_KEY else []
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    nan = math.nan
    lost = sum(r.lost_share * r.steps for r in rs) / steps
    fit = consistency.pooled([ep.nees[key] for ep in eps], [np.isfinite(ep.estimates[key][:, 0]) for ep in eps])
    return Summary(
        key, eps[0].crowd_size, len(rs), spread.mean, spread.sd,
        float(np.median(err)) if err.size else nan, float(np.percentile(err, 95)) if err.size else nan,
        float(err.max()) if err.size else nan, float(head.mean()) if head.size else nan,
        sum(r.failure_share * r.steps for r in rs) / steps, lost, 1.0 - lost,
        sum(r.bad_share > 0 for r in rs),
        float(d.mean()) if d.size else nan, float(d.max()) if d.size else nan,
        tuple(float(x.max()) if x.size else nan for x in diffs),
        fit.nees_median, fit.inside_95, consistency.missing_share(fit),
    )  # fmt: skip


Table = Mapping[tuple[str, int], Summary]


def summary_table(episodes: Sequence[Episode]) -> dict[tuple[str, int], Summary]:
    """:class:`Summary` per (localizer key, crowd size)."""
    crowds = sorted({ep.crowd_size for ep in episodes})
    return {(key, n): summarize([ep for ep in episodes if ep.crowd_size == n], key) for n in crowds for key in KEYS}


def first_failing(table: Table, key: str) -> int | None:
    """The first crowd size at which a localizer fails (:attr:`Summary.fails`), None when it never does."""
    return next((n for (k, n), s in sorted(table.items(), key=lambda kv: kv[0][1]) if k == key and s.fails), None)


# ------------------------------------------------------------------------------------ paired comparisons


PAIRS: tuple[tuple[str, str], ...] = (
    (PAPER_SELECTION, "all"),
    (PAPER_SELECTION, "nearest"),
    (PAPER_SELECTION, REFERENCE_KEY),
    ("all", REFERENCE_KEY),
)


@dataclass(frozen=True)
class Paired:
    """Localizer ``a`` against ``b`` on the same runs of one crowd size: per seed the difference
    ``a - b`` of the mean error and of the share of failed or lost steps.

    Attributes:
        differences_m: per seed, mean error of a minus b (NaN where either has no pose at all).
        mean_m, ci_m: their mean and its bootstrap 95 % interval.
        a_better: seeds where a's mean error is lower.
        bad_mean, bad_ci: the same for the share of failed or lost steps.
    """

    a: str
    b: str
    crowd_size: int
    differences_m: tuple[float, ...]
    mean_m: float
    ci_m: tuple[float, float]
    a_better: int
    bad_mean: float
    bad_ci: tuple[float, float]

    @property
    def resolved(self) -> int:
        """-1: a's error is lower (the interval below 0), +1: higher, 0: not resolved."""
        lo, hi = self.ci_m
        return -1 if hi < 0 else 1 if lo > 0 else 0


def paired(episodes: Sequence[Episode], a: str, b: str, crowd_size: int, stream: int) -> Paired:
    eps = sorted((ep for ep in episodes if ep.crowd_size == crowd_size), key=lambda e: e.seed)
    ra, rb = [run_stats(ep, a) for ep in eps], [run_stats(ep, b) for ep in eps]
    d = np.array([x.mean_m - y.mean_m for x, y in zip(ra, rb)])
    bad = np.array([x.bad_share - y.bad_share for x, y in zip(ra, rb)])
    rng = np.random.default_rng([BOOTSTRAP_SEED, crowd_size, stream])
    ci = bootstrap_ci(d, BOOTSTRAP_RESAMPLES, rng=rng)
    bad_ci = bootstrap_ci(bad, BOOTSTRAP_RESAMPLES, rng=np.random.default_rng([BOOTSTRAP_SEED, crowd_size, stream, 1]))
    fd = d[np.isfinite(d)]
    return Paired(a, b, crowd_size, tuple(float(x) for x in d), float(fd.mean()) if fd.size else math.nan, ci,
                  int(np.count_nonzero(fd < 0)), float(bad.mean()), bad_ci)  # fmt: skip


def paired_table(episodes: Sequence[Episode]) -> dict[tuple[str, str, int], Paired]:
    """:class:`Paired` of every pair of :data:`PAIRS` at every crowd size."""
    crowds = sorted({ep.crowd_size for ep in episodes})
    return {(a, b, n): paired(episodes, a, b, n, i) for n in crowds for i, (a, b) in enumerate(PAIRS)}


@dataclass(frozen=True)
class Growth:
    """How much a localizer's mean error grows from the emptiest to the densest crowd, against another's.

    ``growth_a_m`` / ``growth_b_m``: mean over seeds of (densest - emptiest) per-run mean error;
    ``difference_ci_m``: bootstrap interval of the mean of their per-seed difference (a - b)."""

    a: str
    b: str
    low: int
    high: int
    growth_a_m: float
    growth_b_m: float
    difference_m: float
    difference_ci_m: tuple[float, float]


def growth(episodes: Sequence[Episode], a: str, b: str) -> Growth | None:
    """None with a single crowd size."""
    crowds = sorted({ep.crowd_size for ep in episodes})
    if len(crowds) < 2:
        return None
    lo, hi = crowds[0], crowds[-1]
    by = {(ep.seed, ep.crowd_size): ep for ep in episodes}
    seeds = sorted({s for s, n in by if n == lo} & {s for s, n in by if n == hi})

    def g(key: str) -> Array:
        return np.array([run_stats(by[s, hi], key).mean_m - run_stats(by[s, lo], key).mean_m for s in seeds])

    ga, gb = g(a), g(b)
    d = ga - gb
    ci = bootstrap_ci(d, BOOTSTRAP_RESAMPLES, rng=np.random.default_rng([BOOTSTRAP_SEED, lo, hi, 7]))
    return Growth(a, b, lo, hi, float(np.nanmean(ga)), float(np.nanmean(gb)), float(np.nanmean(d)), ci)


# ------------------------------------------------------------------------------------ detections


def sectors_in_view() -> int:
    """How many of far emphasis's sectors the camera's field of view spans (``floor((theta + pi) / sector)``)."""
    cam = world.camera()
    half = math.atan(0.5 * cam.width_px / cam.focal_px)
    sector = world.far_landmark_defaults().sector_rad
    lo, hi = math.floor((-half + math.pi) / sector), math.floor((half - 1e-12 + math.pi) / sector)
    return int(hi - lo + 1)


def fov_deg() -> float:
    cam = world.camera()
    return math.degrees(2.0 * math.atan(0.5 * cam.width_px / cam.focal_px))


@dataclass(frozen=True)
class Detections:
    """The stereo camera's detections at one crowd size, over every frame of every run.

    Attributes:
        per_frame, far_per_frame, used_per_frame: means a frame of the matched edges, of those at
            least ``min_range_m`` away, of those far emphasis weighed (the paper's selection).
        slots_full: share of frames with every slot of the camera filled.
        below_sectors: share of frames where far emphasis weighed fewer detections than it has
            sectors in view (a sector without a matching one).
        sparse_share: share of frames in a stretch of "few landmarks" (:func:`sparse_mask`).
        near_beams: the LIDAR's beams within ``NEAR_M`` a frame (how much of the surroundings the crowd fills).
    """

    crowd_size: int
    per_frame: float
    far_per_frame: float
    used_per_frame: float
    slots_full: float
    below_sectors: float
    sparse_share: float
    near_beams: float


def sparse_mask(ep: Episode) -> NDArray[np.bool_]:
    """``(T,)`` the frames of a "few landmarks" stretch: far emphasis weighed at most ``SPARSE_USED``
    detections a frame on average over the ``SPARSE_WINDOW_S`` ending there."""
    dt = float(np.median(np.diff(ep.time_s))) if ep.steps > 1 else 1.0
    w = max(1, round(SPARSE_WINDOW_S / dt))
    c = np.concatenate([[0.0], np.cumsum(ep.used, dtype=np.float64)])
    k = np.arange(ep.steps)
    start = np.maximum(0, k + 1 - w)
    mean = (c[k + 1] - c[start]) / (k + 1 - start)
    return np.asarray(mean <= SPARSE_USED)


def detections(episodes: Sequence[Episode]) -> list[Detections]:
    slots = int(world.camera().slots)
    sectors = sectors_in_view()
    out = []
    for n in sorted({ep.crowd_size for ep in episodes}):
        eps = [ep for ep in episodes if ep.crowd_size == n]
        det = np.concatenate([ep.detections for ep in eps])
        used = np.concatenate([ep.used for ep in eps])
        out.append(Detections(
            n, float(det.mean()), float(np.concatenate([ep.far_detections for ep in eps]).mean()), float(used.mean()),
            float(np.mean(det >= slots)), float(np.mean(used < sectors)), float(np.concatenate([sparse_mask(ep) for ep in eps]).mean()),
            float(np.concatenate([ep.near_beams for ep in eps]).mean()),
        ))  # fmt: skip
    return out


@dataclass(frozen=True)
class Profile:
    """Along the route at one crowd size, per 1 m of arc length: means over every frame and run."""

    arc_m: Array  # (B,) bin centres
    detections: Array
    far_detections: Array
    used: Array
    error_m: dict[str, Array]  # key -> mean error against the truth
    difference_m: Array  # the paper's selection's distance to the reference


def profile(episodes: Sequence[Episode], crowd_size: int, bin_m: float = 1.0) -> Profile:
    eps = [ep for ep in episodes if ep.crowd_size == crowd_size]
    edges = np.arange(0.0, world.route_length_m() + bin_m, bin_m)
    arc = np.concatenate([ep.arc_m for ep in eps])
    b = np.clip(np.digitize(arc, edges) - 1, 0, edges.size - 2)

    def mean(values: Array) -> Array:
        v = np.asarray(values, dtype=np.float64)
        ok = np.isfinite(v)
        s = np.bincount(b[ok], weights=v[ok], minlength=edges.size - 1)
        n = np.bincount(b[ok], minlength=edges.size - 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, s / np.maximum(n, 1), np.nan)

    cat = np.concatenate
    return Profile(
        0.5 * (edges[:-1] + edges[1:]),
        mean(cat([ep.detections for ep in eps])), mean(cat([ep.far_detections for ep in eps])), mean(cat([ep.used for ep in eps])),
        {key: mean(cat([errors_m(ep, key) for ep in eps])) for key in KEYS},
        mean(cat([difference_m(ep, PAPER_SELECTION) for ep in eps])),
    )  # fmt: skip


# ------------------------------------------------------------------------------------ the weak spot


@dataclass(frozen=True)
class WeakSpot:
    """The paper's weak spot on its measure (the distance to the reference) at its crowd size.

    Attributes:
        sparse_share: frames in a "few landmarks" stretch (:func:`sparse_mask`).
        rate_sparse_mps, rate_rich_mps: mean change of the distance to the reference per second
            in those frames and in the others (NaN without such frames).
        peaks_m: per run, the largest distance to the reference (averaged over ``SMOOTH_S``, as all here).
        corrected: per run, whether the distance fell to half its peak within ``CORRECTION_S`` after it.
        correction_s: per run, how long that took (NaN: it did not).
        corrected_by_end: per run, whether it fell to half its peak at any time after it.
    """

    sparse_share: float
    rate_sparse_mps: float
    rate_rich_mps: float
    peaks_m: tuple[float, ...]
    corrected: tuple[bool, ...]
    correction_s: tuple[float, ...]
    corrected_by_end: tuple[bool, ...]


def smoothed(values: Array, time_s: Array, window_s: float = SMOOTH_S) -> Array:
    """``values`` averaged over a centred window of ``window_s`` (NaN entries left out; NaN where the window has none)."""
    dt = float(np.median(np.diff(time_s))) if time_s.size > 1 else 1.0
    half = max(0, round(window_s / dt) // 2)
    ok = np.isfinite(values)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, values, 0.0))])
    n = np.concatenate([[0], np.cumsum(ok)])
    k = np.arange(values.size)
    lo, hi = np.maximum(0, k - half), np.minimum(values.size, k + half + 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(np.where(n[hi] > n[lo], (c[hi] - c[lo]) / np.maximum(n[hi] - n[lo], 1), np.nan), dtype=np.float64)


def weak_spot(episodes: Sequence[Episode], crowd_size: int) -> WeakSpot:
    eps = sorted((ep for ep in episodes if ep.crowd_size == crowd_size), key=lambda e: e.seed)
    rates: dict[bool, list[Array]] = {True: [], False: []}
    sparse_n = total = 0
    peaks, corrected, after, by_end = [], [], [], []
    for ep in eps:
        d = smoothed(difference_m(ep, PAPER_SELECTION), ep.time_s)
        sparse = sparse_mask(ep)
        sparse_n += int(sparse.sum())
        total += ep.steps
        rate = np.diff(d) / np.diff(ep.time_s)
        for flag in (True, False):
            rates[flag].append(rate[sparse[1:] == flag])
        if not np.isfinite(d).any():
            peaks.append(math.nan)
            corrected.append(False)
            after.append(math.nan)
            by_end.append(False)
            continue
        k = int(np.nanargmax(d))
        peak = float(d[k])
        later = np.flatnonzero((ep.time_s > ep.time_s[k]) & (ep.time_s <= ep.time_s[k] + CORRECTION_S) & (d <= 0.5 * peak))
        peaks.append(peak)
        corrected.append(bool(later.size))
        after.append(float(ep.time_s[later[0]] - ep.time_s[k]) if later.size else math.nan)
        by_end.append(bool(np.any((ep.time_s > ep.time_s[k]) & (d <= 0.5 * peak))))

    def mean_rate(flag: bool) -> float:
        r = np.concatenate(rates[flag]) if rates[flag] else np.zeros(0)
        r = r[np.isfinite(r)]
        return float(r.mean()) if r.size else math.nan

    return WeakSpot(sparse_n / max(total, 1), mean_rate(True), mean_rate(False), tuple(peaks), tuple(corrected), tuple(after),
                    tuple(by_end))  # fmt: skip


# ------------------------------------------------------------------------------------ the claims


@dataclass(frozen=True)
class Verdict:
    """One claim checked against our numbers: its id, the outcome and the numbers it rests on."""

    claim_id: str
    verdict: Outcome
    numbers: dict[str, Any]


#: ours: C2 is testable when at least this share of the frames is in a "few landmarks" stretch
MIN_SPARSE_SHARE = 0.01


def _outcome(full: bool, part: bool) -> Outcome:
    return "holds" if full else "partly holds" if part else "does not hold"


def _c1(table: Table, crowd: int) -> Verdict:
    s = table[PAPER_SELECTION, crowd]
    limit = ABOUT * paper.MAX_DIFFERENCE_M
    maxima = [m for m in s.diff_run_max_m if math.isfinite(m)]
    within = sum(m <= limit for m in maxima)
    numbers = {"limit_m": limit, "runs": len(s.diff_run_max_m), "runs_within": within, "run_max_m": list(s.diff_run_max_m),
               "max_m": s.diff_max_m, "median_run_max_m": float(np.median(maxima)) if maxima else math.nan,
               "mean_m": s.diff_mean_m, "reference_max_vs_truth_m": table[REFERENCE_KEY, crowd].max_m,
               "max_vs_truth_m": s.max_m}  # fmt: skip
    full = bool(maxima) and within == len(s.diff_run_max_m)
    return Verdict("C1", _outcome(full, 2 * within >= len(s.diff_run_max_m) and within > 0), numbers)


def _c2(ws: WeakSpot) -> Verdict:
    numbers = {"sparse_share": ws.sparse_share, "rate_sparse_mps": ws.rate_sparse_mps, "rate_rich_mps": ws.rate_rich_mps,
               "sparse_used": SPARSE_USED, "window_s": SPARSE_WINDOW_S, "min_share": MIN_SPARSE_SHARE}  # fmt: skip
    if ws.sparse_share < MIN_SPARSE_SHARE or not math.isfinite(ws.rate_sparse_mps):
        return Verdict("C2", "not testable here", numbers)
    return Verdict(
        "C2", _outcome(ws.rate_sparse_mps > max(ws.rate_rich_mps, 0.0), ws.rate_sparse_mps > ws.rate_rich_mps), numbers
    )


def _c3(ws: WeakSpot) -> Verdict:
    n = len(ws.corrected)
    k = sum(ws.corrected)
    times = [t for t in ws.correction_s if math.isfinite(t)]
    numbers = {"runs": n, "corrected": k, "window_s": CORRECTION_S, "peaks_m": list(ws.peaks_m), "by_end": sum(ws.corrected_by_end),
               "median_correction_s": float(np.median(times)) if times else math.nan}  # fmt: skip
    return Verdict("C3", _outcome(n > 0 and k == n, 2 * k >= n and k > 0), numbers)


def _compare(claim_id: str, pairs: Mapping[tuple[str, str, int], Paired], a: str, b: str, crowds: Sequence[int]) -> Verdict:
    """``a`` has the lower mean error than ``b`` among crowds: at the densest crowd by the paired interval
    (holds), or by its mean there or by the interval at another crowd (partly)."""
    rows = [pairs[a, b, n] for n in crowds]
    top = rows[-1]
    numbers = {
        "crowd_sizes": list(crowds), "mean_m": [p.mean_m for p in rows], "ci_m": [list(p.ci_m) for p in rows],
        "a_better": [p.a_better for p in rows], "runs": [len(p.differences_m) for p in rows],
        "lower_at": [p.crowd_size for p in rows if p.resolved < 0], "higher_at": [p.crowd_size for p in rows if p.resolved > 0],
    }  # fmt: skip
    full = top.resolved < 0
    return Verdict(claim_id, _outcome(full, top.mean_m < 0 or bool(numbers["lower_at"])), numbers)


def _c6(g: Growth | None) -> Verdict:
    if g is None:
        return Verdict("C6", "not testable here", {})
    numbers = dataclasses.asdict(g)
    return Verdict("C6", _outcome(g.difference_ci_m[1] < 0, g.difference_m < 0), numbers)


def claim_verdicts(plan: Plan, table: Table, pairs: Mapping[tuple[str, str, int], Paired], ws: WeakSpot,
                   episodes: Sequence[Episode]) -> list[Verdict]:  # fmt: skip
    """The paper's claims C1..C3 and the beyond-paper ones C4..C7, each with a fixed criterion."""
    crowds = sorted({n for _, n in table})
    dense = [n for n in crowds if n > plan.crowd] or crowds[-1:]
    return [
        _c1(table, plan.crowd),
        _c2(ws),
        _c3(ws),
        _compare("C4", pairs, PAPER_SELECTION, "all", dense),
        _compare("C5", pairs, PAPER_SELECTION, "nearest", dense),
        _c6(growth(episodes, PAPER_SELECTION, "all")),
        _compare("C7", pairs, PAPER_SELECTION, REFERENCE_KEY, dense),
    ]


# ------------------------------------------------------------------------------------ the runs


@dataclass(frozen=True)
class Facts:
    """What the runs show beside the localizers (means over runs unless said otherwise)."""

    scenes: float
    landmarks: float
    map_s: float
    reached: dict[int, tuple[int, int]]  # crowd size -> (runs that reached the goal, runs)
    duration_s: dict[int, float]
    blocked_s: dict[int, float]
    contacts: dict[int, float]
    record_s: float
    replay_s: dict[str, float]
    cpu_s: float
    identity_m: float


def facts(maps: Sequence[MapResult], episodes: Sequence[Episode]) -> Facts:
    crowds = sorted({ep.crowd_size for ep in episodes})

    def per(fn: Any) -> dict[int, float]:
        return {n: float(np.mean([fn(ep) for ep in episodes if ep.crowd_size == n])) for n in crowds}

    return Facts(
        float(np.mean([m.scenes.scene_count for m in maps])), float(np.mean([m.scenes.landmark_count for m in maps])),
        float(np.mean([m.seconds for m in maps])),
        {n: (sum(ep.reached_goal for ep in episodes if ep.crowd_size == n), sum(ep.crowd_size == n for ep in episodes))
         for n in crowds},
        per(lambda ep: float(ep.time_s[-1])), per(lambda ep: ep.blocked_s), per(lambda ep: float(ep.contacts)),
        float(np.mean([ep.record_s for ep in episodes])),
        {k: float(np.mean([ep.replay_s[k] for ep in episodes])) for k in KEYS},
        sum(ep.cpu_s for ep in episodes), max(ep.identity_m for ep in episodes),
    )  # fmt: skip


# ------------------------------------------------------------------------------------ results.json


def fig10_series(episodes: Sequence[Episode], crowd_size: int, period_s: float = paper.PLOT_PERIOD_S) -> list[dict[str, Any]]:
    """Per run at ``crowd_size``, once a ``period_s``: the time, far_landmark_pf's distance to the
    reference and both errors against the truth (the data of Figs 8-10)."""
    out = []
    for ep in sorted((e for e in episodes if e.crowd_size == crowd_size), key=lambda e: e.seed):
        dt = float(np.median(np.diff(ep.time_s)))
        k = np.arange(0, ep.steps, max(1, round(period_s / dt)))
        out.append({"seed": ep.seed, "time_s": ep.time_s[k].tolist(), "difference_m": difference_m(ep, PAPER_SELECTION)[k].tolist(),
                    "error_m": errors_m(ep, PAPER_SELECTION)[k].tolist(), "reference_error_m": errors_m(ep, REFERENCE_KEY)[k].tolist()})  # fmt: skip
    return out


def results_data(plan: Plan, table: Table, pairs: Mapping[tuple[str, str, int], Paired], dets: Sequence[Detections],
                 ws: WeakSpot, episodes: Sequence[Episode], verdicts: Sequence[Mapping[str, Any]], f: Facts,
                 wall_s: float, workers: int) -> dict[str, Any]:  # fmt: skip
    """Everything ``results.json`` holds (timings under ``timing``)."""
    return {
        "plan": dataclasses.asdict(plan),
        "paper_crowd": plan.crowd,
        "identity_max_difference_m": f.identity_m,
        "summaries": {f"{k}@{n}": dataclasses.asdict(s) for (k, n), s in table.items()},
        "paired": {f"{a}-{b}@{n}": dataclasses.asdict(p) for (a, b, n), p in pairs.items()},
        "detections": [dataclasses.asdict(d) for d in dets],
        "weak_spot": dataclasses.asdict(ws),
        "verdicts": list(verdicts),
        "failing_from": {k: first_failing(table, k) for k in KEYS},
        "runs": [dataclasses.asdict(r) for r in all_run_stats(episodes)],
        "drives": [
            {
                "seed": ep.seed,
                "crowd_size": ep.crowd_size,
                "steps": ep.steps,
                "reached_goal": ep.reached_goal,
                "contacts": ep.contacts,
                "blocked_s": ep.blocked_s,
            }
            for ep in episodes
        ],  # fmt: skip
        "maps": {"scenes": f.scenes, "landmarks": f.landmarks},
        "fig10": fig10_series(episodes, plan.crowd),
        "timing": {
            "wall_s": wall_s,
            "workers": workers,
            "cpu_s": f.cpu_s,
            "map_s": f.map_s,
            "record_s": f.record_s,
            "replay_s": f.replay_s,
        },  # fmt: skip
    }
