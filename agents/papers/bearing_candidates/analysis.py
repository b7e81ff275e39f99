"""Statistics of the candidate-set reproduction, as data (dataclasses and dicts, no prose).

:func:`analyze` turns the job results into one :class:`Analysis`; :func:`results_json` is
what ``results.json`` holds. Errors are taken "from the first fix of method (5) on", as the
paper does (:func:`references` says whose first fix starts each method's statistics).

Exp 1's errors exist on two measures (:data:`MEASURES`): ``"path"``, the distance from each
estimate to the line drawn on the floor (``jobs.EXP1_DRAWN_PATH``), which is what the paper
measured, and ``"true"``, the error against the simulator's true pose (Table 1's columns).
The paper's Exp 1 claims (:data:`EXP1_CLAIMS`) are judged on the paper's measure, the true
error beside it (:class:`Exp1Claim`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.evaluate import consistency, metrics
from agents.evaluate.stats import bootstrap_ci
from agents.papers.bearing_candidates.jobs import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    EXP1_DRAWN_PATH,
    EXP1_METHODS,
    EXP1_OURS,
    EXP1_TABLE_METHODS,
    EXP2_METHODS,
    EXP2_OURS,
    EXP2_TABLE_METHODS,
    EXP3_METHODS,
    EXP3_OURS,
    FAIL_M,
    PUSH_AT_S,
    PUSH_BEFORE_S,
    PUSH_PEAK_S,
    PUSH_SECONDS,
    PUSH_WINDOW_S,
    RECOVER_HOLD_S,
    RECOVER_M,
    REFERENCE,
    STUDIES,
    SWEEP_METHODS,
    SWEEP_WARMUP_S,
    JobResult,
    Method,
    MethodRun,
    Plan,
)

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Row:
    """One method's statistics over the seeds of a study."""

    key: str
    label: str
    pos_mm: tuple[float, float]  # seed-mean of the per-seed mean, seed-mean of the per-seed sd
    head_deg: tuple[float, float]
    pos_seed_sd_mm: float  # sd over seeds of the per-seed mean
    pos_seed_median_mm: float  # median over seeds of the per-seed mean
    first_fix_mm: tuple[float, float, int]  # mean, sd over seeds, seeds that fixed
    first_fix_median_mm: float
    first_fix_s: float
    availability: float
    failure: float
    bound_mm: float
    ratio: float
    seeds: int
    covariance: bool  # the localizer reports one (LocalizerSpec.covariance): the NEES columns are meaningful
    nees_median: float  # over the steps of every seed whose errors the row counts (valid, from the first fix)
    inside_95: float  # share of those steps inside the reported 95 % region
    covariance_missing: float  # share of those steps without a usable covariance (left out of the two above)


def references(methods: Sequence[Method]) -> dict[str, str]:
    """Whose first fix starts each method's statistics: the other variants of (5) (shipped
    thresholds, K = 1, 5) their own, everything else that of the reference method (5)."""
    return {m.key: m.key if m.localizer == "candidate_sets" else REFERENCE for m in methods}


def _nanmedian(values: Sequence[float]) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else float("nan")


def counted(run: MethodRun, start: int | None, stop: int | None = None) -> NDArray[np.bool_]:
    """``(T,)`` the steps whose errors a statistic from ``start`` (None: none) to ``stop`` counts: those with a pose."""
    mask = np.zeros(run.valid.size, dtype=bool)
    if start is not None:
        mask[start:stop] = run.valid[start:stop]
    return mask


Span = tuple[int | None, int | None]  # (start, stop) of a statistic's steps; start None: no steps


def fit_over(runs: Sequence[MethodRun], spans: Sequence[Span]) -> metrics.Consistency:
    """NEES of the runs over the steps of :func:`counted` in each run's span, every run's steps pooled."""
    return consistency.pooled([r.nees for r in runs], [counted(r, *span) for r, span in zip(runs, spans, strict=True)])


def study_rows(results: Sequence[JobResult], methods: Sequence[Method], reference: Mapping[str, str]) -> list[Row]:
    """Per-method statistics "from the first fix of method (5) on" over the seeds.

    ``reference[key]`` names the method whose first fix starts the statistics of ``key``;
    the NEES is over the same steps as the errors, all seeds' steps pooled.
    """
    rows = []
    for m in methods:
        fit = fit_over(
            [r.runs[m.key] for r in results], [(metrics.first_fix(r.runs[reference[m.key]].valid), None) for r in results]
        )
        per: dict[str, list[float]] = {k: [] for k in ("pm", "ps", "hm", "hs", "ffd", "fft", "av", "fail", "bnd", "ratio")}
        for r in results:
            run = r.runs[m.key]
            t0 = metrics.first_fix(r.runs[reference[m.key]].valid)
            ff = metrics.first_fix(run.valid)
            pm, ps = metrics.mean_sd(run.position_error_m * 1000.0, t0)
            hm, hs = metrics.mean_sd(np.degrees(run.heading_error_rad), t0)
            per["pm"].append(pm)
            per["ps"].append(ps)
            per["hm"].append(hm)
            per["hs"].append(hs)
            per["ffd"].append(metrics.travelled(r.truth)[ff] * 1000.0 if ff is not None else np.nan)
            per["fft"].append(r.time_s[ff] - r.time_s[0] if ff is not None else np.nan)
            per["av"].append(metrics.availability(run.valid))
            per["fail"].append(metrics.failure_rate(run.position_error_m, t0, FAIL_M))
            valid_from = np.isfinite(run.position_error_m)
            per["bnd"].append(metrics.rms(run.bound_m * 1000.0, t0, valid_from))
            per["ratio"].append(metrics.error_bound_ratio(run.position_error_m, run.bound_m, t0))
        s = {k: metrics.over_seeds(v) for k, v in per.items()}
        rows.append(
            Row(
                m.key, m.label, (s["pm"].mean, s["ps"].mean), (s["hm"].mean, s["hs"].mean), s["pm"].sd,
                _nanmedian(per["pm"]), (s["ffd"].mean, s["ffd"].sd, s["ffd"].n), _nanmedian(per["ffd"]),
                s["fft"].mean, s["av"].mean, s["fail"].mean,
                s["bnd"].mean, s["ratio"].mean, len(results),
                consistency.reports_covariance(m.localizer), fit.nees_median, fit.inside_95, consistency.missing_share(fit),
            )
        )  # fmt: skip
    return rows


def per_seed(
    results: Sequence[JobResult], methods: Sequence[Method], reference: Mapping[str, str], *, drawn_path: bool = False
) -> dict[str, list[dict[str, Any]]]:
    """Per method, one record per seed: mean position / heading error from the reference first fix,
    first-fix distance and availability (for results.json); with ``drawn_path`` (Exp 1) also the
    mean and sd of the distance to the drawn path over the same steps (``path_mm``)."""
    out: dict[str, list[dict[str, Any]]] = {}
    for m in methods:
        rows = []
        for r in results:
            run = r.runs[m.key]
            t0 = metrics.first_fix(r.runs[reference[m.key]].valid)
            ff = metrics.first_fix(run.valid)
            fit = fit_over([run], [(t0, None)])
            rows.append({
                "seed": r.job.seed,
                "position_mm": metrics.mean_sd(run.position_error_m * 1000.0, t0),
                "heading_deg": metrics.mean_sd(np.degrees(run.heading_error_rad), t0),
                "first_fix_mm": metrics.travelled(r.truth)[ff] * 1000.0 if ff is not None else None,
                "availability": metrics.availability(run.valid),
                "nees_median": fit.nees_median,
                "inside_95": fit.inside_95,
                "covariance_missing": consistency.missing_share(fit),
            })  # fmt: skip
            if drawn_path:
                rows[-1]["path_mm"] = metrics.mean_sd(measured_errors_mm(r, m.key, "path"), t0)
        out[m.key] = rows
    return out


@dataclass(frozen=True)
class SweepCell:
    """One method at one swept value, over the window ``t >= SWEEP_WARMUP_S``.

    Attributes:
        err: seed mean, sd and count of the per-seed mean position error [mm].
        avail: seed mean and sd of the availability.
        fail: seed mean of the share of steps with error >= ``FAIL_M``.
        seeds: runs at this value.
        nees_median, inside_95: the NEES over the window's steps with a pose, all seeds pooled.
        covariance_missing: share of those steps without a usable covariance (left out of the two).
    """

    err: tuple[float, float, int]
    avail: tuple[float, float]
    fail: float
    seeds: int
    nees_median: float
    inside_95: float
    covariance_missing: float


def sweep_stats(results: Sequence[JobResult], methods: Sequence[Method]) -> dict[str, dict[float, SweepCell]]:
    """Per method and swept value, the :class:`SweepCell`."""
    out: dict[str, dict[float, SweepCell]] = {m.key: {} for m in methods}
    points = sorted({r.job.point for r in results})
    for m in methods:
        for p in points:
            runs = [r for r in results if r.job.point == p]
            err, av, fail, spans = [], [], [], []
            for r in runs:
                run = r.runs[m.key]
                start = int(np.searchsorted(r.time_s - r.time_s[0], SWEEP_WARMUP_S))
                spans.append((start, None))
                err.append(metrics.mean_sd(run.position_error_m * 1000.0, start)[0])
                av.append(metrics.availability(run.valid, start))
                fail.append(metrics.failure_rate(run.position_error_m, start, FAIL_M))
            e, a, f = metrics.over_seeds(err), metrics.over_seeds(av), metrics.over_seeds(fail)
            fit = fit_over([r.runs[m.key] for r in runs], spans)
            out[m.key][p] = SweepCell((e.mean, e.sd, e.n), (a.mean, a.sd), f.mean, len(runs), fit.nees_median, fit.inside_95,
                                      consistency.missing_share(fit))  # fmt: skip
    return out


@dataclass(frozen=True)
class PushStats:
    """One method around the shove, over the seeds.

    Attributes:
        curve: median, lower and upper quartile of the error [m] at the times ``t_rel``.
        recover_s: per seed, time from the shove's start until the error stays below
            ``RECOVER_M`` for ``RECOVER_HOLD_S`` (inf: never within the run).
        lost: per seed, whether the error reached ``RECOVER_M`` (or there was no pose)
            within the shove and ``PUSH_PEAK_S`` after it.
        before_mm: seed mean of the mean error over ``PUSH_BEFORE_S`` before the shove.
        peak_mm: seed mean of the peak error within the shove and ``PUSH_PEAK_S`` after it.
        fit_before, fit_peak: the NEES over the steps with a pose of those two windows, all
            seeds pooled (does the covariance grow when the pose is lost?).
    """

    curve: tuple[Array, Array, Array]
    recover_s: Array
    lost: NDArray[np.bool_]
    before_mm: float
    peak_mm: float
    fit_before: metrics.Consistency
    fit_peak: metrics.Consistency

    @property
    def recover_when_lost_s(self) -> Array:
        """The recovery times of the seeds that lost track."""
        return self.recover_s[self.lost]


def _push_index(r: JobResult, at_s: float) -> int:
    return int(np.searchsorted(r.time_s - r.time_s[0], at_s - 1e-9))


def push_stats(results: Sequence[JobResult], methods: Sequence[Method]) -> tuple[Array, dict[str, PushStats]]:
    """Error curves aligned at the push (median, quartiles over seeds) and recovery times."""
    lo, hi = PUSH_WINDOW_S
    dt = results[0].dt_s
    t_rel = np.asarray(np.arange(round(lo / dt), round(hi / dt) + 1) * dt, dtype=np.float64)
    out: dict[str, PushStats] = {}
    for m in methods:
        curves, recover, before, peak, lost = [], [], [], [], []
        before_at: list[Span] = []
        peak_at: list[Span] = []
        for r in results:
            run = r.runs[m.key]
            t = r.time_s - r.time_s[0]
            k0 = _push_index(r, PUSH_AT_S)
            idx = k0 + np.round(t_rel / dt).astype(int)
            inside = (idx >= 0) & (idx < t.size)
            e = np.full(t_rel.size, np.nan)
            e[inside] = run.position_error_m[idx[inside]]
            curves.append(e)
            k_pre, k_post = max(0, k0 - round(PUSH_BEFORE_S / dt)), k0 + round((PUSH_SECONDS + PUSH_PEAK_S) / dt)
            before_at.append((k_pre, k0))
            peak_at.append((k0, k_post))
            pre = run.position_error_m[k_pre:k0]
            before.append(float(np.nanmean(pre)) if np.isfinite(pre).any() else np.nan)
            post = run.position_error_m[k0:k_post]
            peak.append(float(np.nanmax(post)) if np.isfinite(post).any() else np.nan)
            lost.append(not (np.isfinite(post).all() and post.max() < RECOVER_M))
            recover.append(metrics.time_to_recover(t, run.position_error_m, PUSH_AT_S, RECOVER_M, RECOVER_HOLD_S))
        c = np.array(curves)
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns (no pose in any seed)
            q = np.nanpercentile(c, [50, 25, 75], axis=0)  # over the seeds with a pose at that time
        out[m.key] = PushStats(
            curve=(q[0], q[1], q[2]),
            recover_s=np.array(recover),
            lost=np.array(lost),
            before_mm=metrics.over_seeds(np.array(before) * 1000.0).mean,
            peak_mm=metrics.over_seeds(np.array(peak) * 1000.0).mean,
            fit_before=fit_over([r.runs[m.key] for r in results], before_at),
            fit_peak=fit_over([r.runs[m.key] for r in results], peak_at),
        )
    return t_rel, out


def unseen_shift_m(results: Sequence[JobResult]) -> float:
    """Seed mean of how far the shove moved the robot beyond what odometry saw: the change of
    dead reckoning's position error vector from the shove's start to its end."""
    shifts = []
    for r in results:
        error = r.runs["dead_reckoning"].estimates[:, :2] - r.truth[:, :2]
        k0, k1 = _push_index(r, PUSH_AT_S), _push_index(r, PUSH_AT_S + PUSH_SECONDS)
        shifts.append(float(np.hypot(*(error[k1] - error[k0]))))
    return metrics.over_seeds(shifts).mean


# ------------------------------------------------------------------------------------ Exp 1 on two measures

Measure = Literal["path", "true"]
Outcome = Literal["holds", "does not hold", "not separated"]
MEASURES: tuple[Measure, ...] = ("path", "true")  # the paper's measure first
#: the paper's Exp 1 claims (Table 1: (5) 100 mm against 383 and 381): (id, the method, the baseline it beats)
EXP1_CLAIMS: tuple[tuple[str, str, str], ...] = (
    ("E1a", "candidate_sets", "kalman"),
    ("E1b", "candidate_sets", "mcl_bearing_paper"),
)


def measured_errors_mm(r: JobResult, key: str, measure: Measure) -> Array:
    """``(T,)`` method ``key``'s error on ``measure`` along an Exp 1 run [mm], NaN where it had no pose."""
    run = r.runs[key]
    if measure == "path":
        return metrics.path_distances(run.estimates, EXP1_DRAWN_PATH, closed=True) * 1000.0
    return run.position_error_m * 1000.0


def _bootstrap(values: ArrayLike, *stream: int) -> tuple[float, float]:
    """The 95 % percentile-bootstrap interval of the mean of the finite ``values``, from generator
    ``default_rng([BOOTSTRAP_SEED, *stream])``."""
    return bootstrap_ci(values, BOOTSTRAP_RESAMPLES, rng=np.random.default_rng([BOOTSTRAP_SEED, *stream]))


@dataclass(frozen=True)
class Measured:
    """One method's errors on one measure over the seeds: the statistics of Table 1's position column.

    Attributes:
        mm: seed mean of the per-seed mean, seed mean of the per-seed sd [mm] (the paper's "mean ± sd").
        seed_median_mm, seed_sd_mm: median and sd over seeds of the per-seed mean.
        ci_mm: 95 % percentile-bootstrap interval of the seed mean of the per-seed mean.
        seeds: seeds with a value.
    """

    mm: tuple[float, float]
    seed_median_mm: float
    seed_sd_mm: float
    ci_mm: tuple[float, float]
    seeds: int


def measured(errors_mm: Sequence[Array], starts: Sequence[int | None], *stream: int) -> Measured:
    """:class:`Measured` of per-seed error series, each counted from its ``start`` (None: no steps)."""
    per = [metrics.mean_sd(e, t0) for e, t0 in zip(errors_mm, starts, strict=True)]
    means, sds = metrics.over_seeds([m for m, _ in per]), metrics.over_seeds([s for _, s in per])
    return Measured((means.mean, sds.mean), _nanmedian([m for m, _ in per]), means.sd, _bootstrap([m for m, _ in per], *stream),
                    means.n)  # fmt: skip


@dataclass(frozen=True)
class PathRow:
    """One Exp 1 method on both measures, over the same steps (those Table 1 counts).

    Attributes:
        path: the distance to the drawn path (the paper's measure).
        true: the error against the true pose (Table 1's position column, with its interval).
    """

    key: str
    label: str
    path: Measured
    true: Measured


def path_rows(results: Sequence[JobResult], methods: Sequence[Method], reference: Mapping[str, str]) -> list[PathRow]:
    """Per method, :class:`PathRow` from the first fix of ``reference[key]`` on (as :func:`study_rows`)."""
    rows = []
    for m in methods:
        starts = [metrics.first_fix(r.runs[reference[m.key]].valid) for r in results]
        k = EXP1_METHODS.index(m)
        both = {ms: measured([measured_errors_mm(r, m.key, ms) for r in results], starts, 1, k, j)
                for j, ms in enumerate(MEASURES)}  # fmt: skip
        rows.append(PathRow(m.key, m.label, both["path"], both["true"]))
    return rows


def robot_off_path(results: Sequence[JobResult]) -> Measured:
    """How far the robot itself was from the drawn path (its true position's distance to it), over
    the steps from method (5)'s first fix on: the open-loop robot drifts off the line, which the
    paper's hand-pushed robot did not; this is what the paper's measure gives a perfect estimate."""
    errors = [metrics.path_distances(r.truth, EXP1_DRAWN_PATH, closed=True) * 1000.0 for r in results]
    return measured(errors, [metrics.first_fix(r.runs[REFERENCE].valid) for r in results], 3)


@dataclass(frozen=True)
class Difference:
    """A method's per-seed mean error minus a baseline's on one measure, over the seeds.

    Attributes:
        mean_mm: the mean over the seeds where both have one.
        ci_mm: its 95 % percentile-bootstrap interval (paired: seeds are resampled together).
        outcome: "holds" when the interval lies below 0 (the method is better), "does not hold"
            when above, "not separated" when it contains 0.
    """

    mean_mm: float
    ci_mm: tuple[float, float]
    outcome: Outcome


def difference(ours: Sequence[float], baseline: Sequence[float], *stream: int) -> Difference:
    """:class:`Difference` of paired per-seed values (``ours - baseline``)."""
    d = np.asarray(ours, dtype=np.float64) - np.asarray(baseline, dtype=np.float64)
    d = d[np.isfinite(d)]
    lo, hi = _bootstrap(d, *stream)
    outcome: Outcome = "holds" if hi < 0.0 else "does not hold" if lo > 0.0 else "not separated"
    return Difference(float(d.mean()) if d.size else float("nan"), (lo, hi), outcome)


@dataclass(frozen=True)
class Exp1Claim:
    """One of the paper's Exp 1 claims, "``method`` is more accurate than ``baseline``", on both measures.

    Attributes:
        claim_id: from :data:`EXP1_CLAIMS`.
        path: the verdict on the paper's measure (the distance to the drawn path).
        true: the verdict on the error against the true pose.
    """

    claim_id: str
    method: str
    baseline: str
    path: Difference
    true: Difference


def exp1_claims(results: Sequence[JobResult]) -> list[Exp1Claim]:
    """Each of :data:`EXP1_CLAIMS` on both measures, from the per-seed means of Table 1's steps."""
    ref = references(EXP1_TABLE_METHODS)
    out = []
    for c, (claim_id, method, baseline) in enumerate(EXP1_CLAIMS):

        def means(key: str, ms: Measure) -> list[float]:
            return [
                metrics.mean_sd(measured_errors_mm(r, key, ms), metrics.first_fix(r.runs[ref[key]].valid))[0] for r in results
            ]

        diffs = {ms: difference(means(method, ms), means(baseline, ms), 2, c, j) for j, ms in enumerate(MEASURES)}
        out.append(Exp1Claim(claim_id, method, baseline, diffs["path"], diffs["true"]))
    return out


# ------------------------------------------------------------------------------------ studies


@dataclass(frozen=True)
class Exp1Stats:
    """Exp 1 (Table 1): the rows, per-seed records and what the path looked like."""

    rows: list[Row]
    per_seed: dict[str, list[dict[str, Any]]]
    seeds: int
    path_m: float  # length of seed 0's true path
    all_in_view: float  # share of the steps with every landmark in view (seed mean)
    ours_rows: list[Row]  # the "(ours)" variants (jobs.EXP1_OURS), not in the paper
    path_rows: list[PathRow]  # Table 1's rows, then the "(ours)" ones, on the paper's measure and the true error
    robot_off_path: Measured  # :func:`robot_off_path`
    claims: list[Exp1Claim]  # :func:`exp1_claims`


@dataclass(frozen=True)
class Exp2Stats:
    """Exp 2 and Exp 3 (Tables 2, 3) on the same recordings."""

    rows: list[Row]
    exp3_rows: list[Row]
    per_seed: dict[str, list[dict[str, Any]]]
    seeds: int
    speed_mps: tuple[float, float]  # our robot's maximum and mean true speed
    detected: float  # landmarks reported per frame (seed mean)
    visible: float  # landmarks in sight per frame (seed mean)
    plays: float  # per seed
    contacts: float  # per seed
    ours_rows: list[Row]  # the "(ours)" variants beside Table 2 (jobs.EXP2_OURS), not in the paper
    exp3_ours_rows: list[Row]  # and beside Table 3 (jobs.EXP3_OURS)


@dataclass(frozen=True)
class SweepStudy:
    """A swept study (crowd density, false detections)."""

    points: list[float]
    seeds: int  # per point
    cells: dict[str, dict[float, SweepCell]]  # method key -> point -> cell


@dataclass(frozen=True)
class PushStudy:
    """The shove-recovery study."""

    t_rel: Array  # times of the error curves, relative to the shove's start
    stats: dict[str, PushStats]
    seeds: int
    shift_m: float  # :func:`unseen_shift_m`


@dataclass(frozen=True)
class Analysis:
    """Every study's statistics (``None``: the study was not run)."""

    exp1: Exp1Stats | None
    exp2: Exp2Stats | None
    density: SweepStudy | None
    false: SweepStudy | None
    push: PushStudy | None
    cpu_s: float  # summed run time of the jobs


def exp1_stats(results: Sequence[JobResult]) -> Exp1Stats:
    """Table 1's rows and the path facts."""
    return Exp1Stats(
        rows=study_rows(results, EXP1_TABLE_METHODS, references(EXP1_TABLE_METHODS)),
        per_seed=per_seed(results, EXP1_METHODS, references(EXP1_METHODS), drawn_path=True),
        seeds=len(results),
        path_m=float(metrics.travelled(results[0].truth)[-1]),
        all_in_view=float(np.mean([np.mean(r.visible_count >= r.landmarks_xy.shape[0]) for r in results])),
        ours_rows=study_rows(results, EXP1_OURS, references(EXP1_OURS)),
        path_rows=path_rows(results, EXP1_METHODS, references(EXP1_METHODS)),
        robot_off_path=robot_off_path(results),
        claims=exp1_claims(results),
    )


def exp2_stats(results: Sequence[JobResult]) -> Exp2Stats:
    """Tables 2 and 3 and the scenario's facts."""
    sp = np.concatenate([metrics.speeds(r.truth, r.dt_s) for r in results])
    return Exp2Stats(
        rows=study_rows(results, EXP2_TABLE_METHODS, references(EXP2_TABLE_METHODS)),
        exp3_rows=study_rows(results, EXP3_METHODS, references(EXP3_METHODS)),
        per_seed=per_seed(results, EXP2_METHODS, references(EXP2_METHODS)),
        seeds=len(results),
        speed_mps=(float(np.max(sp)), float(np.mean(sp))),
        detected=float(np.mean([r.detected_count.mean() for r in results])),
        visible=float(np.mean([r.visible_count.mean() for r in results])),
        plays=float(np.mean([r.plays for r in results])),
        contacts=float(np.mean([r.contacts for r in results])),
        ours_rows=study_rows(results, EXP2_OURS, references(EXP2_OURS)),
        exp3_ours_rows=study_rows(results, EXP3_OURS, references(EXP3_OURS)),
    )


def sweep_study(results: Sequence[JobResult]) -> SweepStudy:
    """A swept study over :data:`SWEEP_METHODS`."""
    cells = sweep_stats(results, SWEEP_METHODS)
    first = next(iter(cells.values()))
    return SweepStudy(points=sorted(first), seeds=max(c.seeds for c in first.values()), cells=cells)


def push_study(results: Sequence[JobResult]) -> PushStudy:
    """The shove study over :data:`SWEEP_METHODS`."""
    t_rel, stats = push_stats(results, SWEEP_METHODS)
    return PushStudy(t_rel=t_rel, stats=stats, seeds=len(results), shift_m=unseen_shift_m(results))


def by_study(results: Sequence[JobResult]) -> dict[str, list[JobResult]]:
    """The results of each of :data:`STUDIES` (empty lists for those not run)."""
    return {s: [r for r in results if r.job.study == s] for s in STUDIES}


def analyze(results: Sequence[JobResult]) -> Analysis:
    """Every study's statistics."""
    by = by_study(results)
    return Analysis(
        exp1=exp1_stats(by["exp1"]) if by["exp1"] else None,
        exp2=exp2_stats(by["exp2"]) if by["exp2"] else None,
        density=sweep_study(by["density"]) if by["density"] else None,
        false=sweep_study(by["false"]) if by["false"] else None,
        push=push_study(by["push"]) if by["push"] else None,
        cpu_s=float(sum(r.seconds for r in results)),
    )


def results_json(analysis: Analysis, plan: Plan, wall_s: float, workers: int) -> dict[str, Any]:
    """What ``results.json`` holds: the plan, the table rows, per-seed records and the extra studies."""
    out: dict[str, Any] = {"plan": asdict(plan), "wall_s": wall_s, "workers": workers}
    if analysis.exp1:
        out["exp1"] = [asdict(r) for r in analysis.exp1.rows]
        out["exp1_per_seed"] = analysis.exp1.per_seed
        out["exp1_ours"] = [asdict(r) for r in analysis.exp1.ours_rows]
        out["exp1_path"] = [asdict(r) for r in analysis.exp1.path_rows]
        out["exp1_robot_off_path"] = asdict(analysis.exp1.robot_off_path)
        out["exp1_claims"] = [asdict(c) for c in analysis.exp1.claims]
    if analysis.exp2:
        out["exp2"] = [asdict(r) for r in analysis.exp2.rows]
        out["exp3"] = [asdict(r) for r in analysis.exp2.exp3_rows]
        out["exp2_per_seed"] = analysis.exp2.per_seed
        out["exp2_speed_mps"] = analysis.exp2.speed_mps
        out["exp2_ours"] = [asdict(r) for r in analysis.exp2.ours_rows]
        out["exp3_ours"] = [asdict(r) for r in analysis.exp2.exp3_ours_rows]
    for name, study in (("density", analysis.density), ("false", analysis.false)):
        if study:
            out[name] = {k: {str(p): asdict(c) for p, c in d.items()} for k, d in study.cells.items()}
    if analysis.push:
        out["push"] = {
            k: {
                "recover_s": v.recover_s.tolist(),
                "lost": v.lost.tolist(),
                "before_mm": v.before_mm,
                "peak_mm": v.peak_mm,
                "consistency_before": asdict(v.fit_before),
                "consistency_peak": asdict(v.fit_peak),
            }  # fmt: skip
            for k, v in analysis.push.stats.items()
        }
    return out
