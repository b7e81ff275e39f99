"""Statistics of the runs and the verdicts on the paper's claims, as data (the words are :mod:`.report`'s).

Every statistic exists against two yardsticks (``Against``): ``"reference"``, the reference
pose of the second LIDAR above the crowd (the paper's measure: its failures are estimates
>= ``FAIL_M`` from the reference), and ``"truth"``, the simulator's true pose (ours). The
verdicts on the claims are taken on the paper's measure (:data:`VERDICT_MEASURE`); the
truth-based ones are computed beside them.

Each claim C1..C7 gets a :class:`Verdict`: its id, whether it holds, and the numbers the
verdict rests on. The criteria are fixed here (``ERROR_GROWTH``, ``FLAT_SPREAD`` and the
experiment's ``WORKS_FAILURE_RATE``); the paper's thresholds come from :mod:`.paper`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from agents.evaluate import consistency, metrics
from agents.experiments.replay import Recording

from .experiment import CROWD_SIZE, DENSITY_PARAMS, WORKS_FAILURE_RATE, Pair, Plan, both
from .jobs import REFERENCE_KEY, Episode, Run, reference_runs
from .paper import FAIL_M, HIT_THRESHOLD, HITS, LARGE_FAIL_M, SAMPLING_THRESHOLD

Array = NDArray[np.float64]
Outcome = Literal["holds", "partly holds", "does not hold"]
Against = Literal["reference", "truth"]
StatsTable = Mapping[tuple[str, int], "Stats"]

VERDICT_MEASURE: Against = "reference"  # the paper's claims are about its measure: error against its reference
MEASURES: tuple[Against, ...] = ("reference", "truth")

ERROR_GROWTH = 1.2  # C1: raw MCL's error "grows" when its mean from the threshold up is > 1.2x the mean below
FLAT_SPREAD = 1.5  # C2: the far-point error "stays low" when its largest mean is < 1.5x its smallest
_EPS = 1e-9  # guards the ratios and the threshold comparisons of swept values

# ------------------------------------------------------------------------------------ statistics


@dataclass(frozen=True)
class Stats:
    """One configuration over the seeds (``K`` estimates per run).

    Attributes:
        runs: number of runs (seeds).
        estimates: estimates per run (the same in every run).
        mean_m: mean position error over all estimates (= mean of the per-run means).
        sd_m: standard deviation over all estimates (the paper's sd, pooled over runs).
        seed_sd_m: standard deviation of the per-run mean over the seeds.
        median_m: median error.
        failures: mean failures (>= 1 m) per run; ``failures_sd`` over the seeds.
        failures_total, large_total: failures and those >= 3 m, over all runs.
        failed_runs: runs with at least one failure.
        max_m: largest error.
        failure_heading_deg: median heading error of the failures (NaN without failures).
        failure_rate: failures over all estimates.
    """

    runs: int
    estimates: int
    mean_m: float
    sd_m: float
    seed_sd_m: float
    median_m: float
    failures: float
    failures_sd: float
    failures_total: int
    large_total: int
    failed_runs: int
    max_m: float
    failure_heading_deg: float
    failure_rate: float

    @property
    def works(self) -> bool:
        return self.failure_rate < WORKS_FAILURE_RATE


def errors_against(run: Run, against: Against) -> tuple[Array, Array]:
    """``(K,)`` position and heading errors of a run against the reference or the true pose."""
    if against == "truth":
        return run.errors_m, run.heading_errors_rad
    if against == "reference":
        return run.ref_errors_m, run.ref_heading_errors_rad
    raise ValueError(f"against must be 'reference' or 'truth', got {against!r}")


def stats_of(runs: Sequence[Run], against: Against = "truth") -> Stats:
    """The statistics of one configuration's runs, their errors measured ``against`` the true or the reference pose.

    Raises:
        ValueError: without runs.
    """
    if not runs:
        raise ValueError("stats_of: no runs")
    errors = [errors_against(r, against) for r in runs]
    err = np.concatenate([e for e, _ in errors])
    head = np.concatenate([h for _, h in errors])
    per_run_mean = [metrics.mean_sd(e)[0] for e, _ in errors]
    fails = np.array([metrics.failure_count(e, FAIL_M) for e, _ in errors], dtype=np.float64)
    failed = err >= FAIL_M
    spread = metrics.over_seeds(per_run_mean)
    return Stats(
        runs=len(runs),
        estimates=int(errors[0][0].size),
        mean_m=float(np.mean(err)),
        sd_m=float(np.std(err)),
        seed_sd_m=spread.sd,
        median_m=float(np.median(err)),
        failures=float(fails.mean()),
        failures_sd=float(fails.std(ddof=1)) if fails.size > 1 else 0.0,
        failures_total=int(fails.sum()),
        large_total=metrics.failure_count(err, LARGE_FAIL_M),
        failed_runs=int(np.count_nonzero(fails)),
        max_m=float(np.max(err)),
        failure_heading_deg=float(np.degrees(np.median(head[failed]))) if failed.any() else float("nan"),
        failure_rate=float(failed.mean()),
    )


def table_stats(runs: Sequence[Run], against: Against = "truth") -> dict[tuple[str, int], Stats]:
    """Statistics per (configuration key, crowd size), errors measured ``against`` the true or the reference pose."""
    groups: dict[tuple[str, int], list[Run]] = {}
    for r in runs:
        groups.setdefault((r.key, r.crowd_size), []).append(r)
    return {k: stats_of(sorted(v, key=lambda r: r.seed), against) for k, v in groups.items()}


def reference_stats(episodes: Sequence[Episode]) -> dict[int, Stats]:
    """Per crowd size, the reference pose's own error against the truth (how good the paper's yardstick is here)."""
    st = table_stats(reference_runs(episodes), "truth")
    return {n: s for (key, n), s in sorted(st.items(), key=lambda kv: kv[0][1]) if key == REFERENCE_KEY}


FitTable = Mapping[tuple[str, int], metrics.Consistency]


def fit_of(runs: Sequence[Run]) -> metrics.Consistency:
    """The NEES of runs against the true pose over their estimates (every run's update steps pooled)."""
    return consistency.pooled([r.nees for r in runs], [np.isfinite(r.estimates).all(axis=1) for r in runs])


def fit_table(runs: Sequence[Run]) -> dict[tuple[str, int], metrics.Consistency]:
    """:func:`fit_of` per (configuration key, crowd size), as :func:`table_stats` groups them."""
    groups: dict[tuple[str, int], list[Run]] = {}
    for r in runs:
        groups.setdefault((r.key, r.crowd_size), []).append(r)
    return {k: fit_of(v) for k, v in groups.items()}


def reference_fits(episodes: Sequence[Episode]) -> dict[int, metrics.Consistency]:
    """Per crowd size, the reference pass's NEES against the truth."""
    return {n: fit for (_, n), fit in sorted(fit_table(reference_runs(episodes)).items(), key=lambda kv: kv[0][1])}


def pair_stats(st: StatsTable, pair: Pair, crowd_size: int = CROWD_SIZE) -> tuple[Stats, Stats]:
    """The raw and the far-point statistics of a configuration pair."""
    return st[pair[0].key, crowd_size], st[pair[1].key, crowd_size]


# ------------------------------------------------------------------------------------ the claims


@dataclass(frozen=True)
class Verdict:
    """One of the paper's claims checked against our numbers.

    Attributes:
        claim_id: ``"C1"`` .. ``"C7"``.
        verdict: whether it holds by the claim's criterion.
        numbers: what the verdict rests on (statistics, swept values, counts).
    """

    claim_id: str
    verdict: Outcome
    numbers: dict[str, Any]


@dataclass(frozen=True)
class Sweeps:
    """Both sweeps at the paper's crowd size: the swept values and each variant's statistics."""

    samplings: tuple[float, ...]
    hits: tuple[float, ...]
    raw_s: tuple[Stats, ...]
    far_s: tuple[Stats, ...]
    raw_h: tuple[Stats, ...]
    far_h: tuple[Stats, ...]


def sweeps(plan: Plan, st: StatsTable) -> Sweeps:
    s_pts, h_pts = plan.sampling_configs(), plan.hit_configs()

    def pick(points: Sequence[tuple[float, Pair]], far: bool) -> tuple[Stats, ...]:
        return tuple(st[pair[int(far)].key, CROWD_SIZE] for _, pair in points)

    return Sweeps(tuple(x for x, _ in s_pts), tuple(x for x, _ in h_pts), pick(s_pts, False), pick(s_pts, True),
                  pick(h_pts, False), pick(h_pts, True))  # fmt: skip


def _outcome(full: bool, part: bool) -> Outcome:
    return "holds" if full else "partly holds" if part else "does not hold"


def _avg(stats: Sequence[Stats], mask: Sequence[bool], attr: str) -> float:
    vals = [getattr(s, attr) for s, m in zip(stats, mask) if m]
    return float(np.mean(vals)) if vals else float("nan")


def _from(values: Sequence[float], threshold: float) -> list[bool]:
    return [x >= threshold - _EPS for x in values]


def _where(values: Sequence[float], keep: Sequence[bool]) -> list[float]:
    return [v for v, k in zip(values, keep) if k]


def _c1(sw: Sweeps) -> Verdict:
    hi = _from(sw.samplings, SAMPLING_THRESHOLD)
    lo = [not h for h in hi]
    e_lo, e_hi = _avg(sw.raw_s, lo, "mean_m"), _avg(sw.raw_s, hi, "mean_m")
    f_lo, f_hi = _avg(sw.raw_s, lo, "failure_rate"), _avg(sw.raw_s, hi, "failure_rate")
    grows_e = e_hi > ERROR_GROWTH * e_lo
    grows_f = f_hi > f_lo and f_hi >= WORKS_FAILURE_RATE
    numbers = {"error_below_m": e_lo, "error_from_m": e_hi, "failure_rate_below": f_lo, "failure_rate_from": f_hi}
    return Verdict("C1", _outcome(grows_e and grows_f, grows_e or grows_f), numbers)


def _c2(sw: Sweeps) -> Verdict:
    works = [s.works for s in sw.far_s]
    lo, hi = min(s.mean_m for s in sw.far_s), max(s.mean_m for s in sw.far_s)
    full = all(works) and hi / max(lo, _EPS) < FLAT_SPREAD
    numbers = {
        "far_error_min_m": lo, "far_error_max_m": hi, "samplings": [sw.samplings[0], sw.samplings[-1]],
        "far_failure_rate_max": max(s.failure_rate for s in sw.far_s), "far_works_at": _where(sw.samplings, works),
    }  # fmt: skip
    return Verdict("C2", _outcome(full, sum(works) > sum(s.works for s in sw.raw_s)), numbers)


def _c3(sw: Sweeps) -> Verdict:
    hi = _from(sw.samplings, SAMPLING_THRESHOLD)
    better = [f.mean_m < r.mean_m and f.failures_total <= r.failures_total for f, r, h in zip(sw.far_s, sw.raw_s, hi) if h]
    ratio = _avg(sw.far_s, hi, "mean_m") / max(_avg(sw.raw_s, hi, "mean_m"), _EPS)
    numbers = {"better": sum(better), "of": len(better), "far_raw_error_ratio": ratio}
    return Verdict("C3", _outcome(bool(better) and all(better), any(better)), numbers)


def _c4(sw: Sweeps) -> Verdict:
    hh = _from(sw.hits, HIT_THRESHOLD)
    fail_hi = [not s.works for s, m in zip(sw.raw_h, hh) if m]
    ok_lo = [s.works for s, m in zip(sw.raw_h, hh) if not m]
    large_hi = sum(s.large_total for s, m in zip(sw.raw_h, hh) if m)
    at = next((s for x, s in zip(sw.hits, sw.raw_h) if abs(x - HIT_THRESHOLD) < _EPS), None)
    heads = [s.failure_heading_deg for s, m in zip(sw.raw_h, hh) if m and s.failures_total]
    full = bool(fail_hi) and all(fail_hi) and all(ok_lo) and large_hi > 0
    numbers = {
        "raw_fails_at": _where(sw.hits, [not s.works for s in sw.raw_h]),
        "raw_large_from_threshold": large_hi,
        "failure_heading_deg": float(np.median(heads)) if heads else float("nan"),
        "at_threshold": None if at is None else {
            "failures": at.failures, "estimates": at.estimates, "large_total": at.large_total, "runs": at.runs,
        },
    }  # fmt: skip
    return Verdict("C4", _outcome(full, any(fail_hi) or large_hi > 0), numbers)


def _c5(sw: Sweeps) -> Verdict:
    numbers = {
        "far_large": sum(s.large_total for s in sw.far_h), "far_failures": sum(s.failures_total for s in sw.far_h),
        "raw_large": sum(s.large_total for s in sw.raw_h), "raw_failures": sum(s.failures_total for s in sw.raw_h),
    }  # fmt: skip
    return Verdict("C5", _outcome(numbers["far_large"] == 0, numbers["far_large"] < numbers["raw_large"]), numbers)


def _c6(sw: Sweeps) -> Verdict:
    raw_ok = [s.works for s in sw.raw_s + sw.raw_h]
    far_ok = [s.works for s in sw.far_s + sw.far_h]
    superset = all(f or not r for r, f in zip(raw_ok, far_ok))
    numbers = {
        "sampling_raw_works_at": _where(sw.samplings, [s.works for s in sw.raw_s]),
        "sampling_far_works_at": _where(sw.samplings, [s.works for s in sw.far_s]),
        "hit_raw_works_at": _where(sw.hits, [s.works for s in sw.raw_h]),
        "hit_far_works_at": _where(sw.hits, [s.works for s in sw.far_h]),
        "raw_works": sum(raw_ok), "far_works": sum(far_ok), "of": len(raw_ok), "raw_works_everywhere": all(raw_ok),
        "far_lower_error": sum(f.mean_m < r.mean_m for f, r in zip(sw.far_s + sw.far_h, sw.raw_s + sw.raw_h)),
    }  # fmt: skip
    wider = sum(far_ok) > sum(raw_ok)
    return Verdict("C6", _outcome(superset and wider, wider), numbers)


def _c7(sw: Sweeps) -> Verdict:
    raw = sw.raw_s + sw.raw_h
    numbers = {"raw_works": sum(s.works for s in raw), "of": len(raw), "raw_lowest_error_m": min(s.mean_m for s in raw)}
    return Verdict("C7", _outcome(numbers["raw_works"] > 0, False), numbers)


def claim_verdicts(plan: Plan, st: StatsTable) -> list[Verdict]:
    """The paper's qualitative claims C1..C7, each checked against our numbers with a fixed criterion."""
    sw = sweeps(plan, st)
    return [check(sw) for check in (_c1, _c2, _c3, _c4, _c5, _c6, _c7)]


# ------------------------------------------------------------------------------------ the episodes


def main_episodes(episodes: Sequence[Episode]) -> list[Episode]:
    """The episodes at the paper's crowd size."""
    return [ep for ep in episodes if ep.task.crowd_size == CROWD_SIZE]


def beam_pct(beams: Sequence[NDArray[np.int64]]) -> Array:
    """``(4,)`` mean share in % of the beams on the wall, short of it, past it, at maximum range."""
    b = np.concatenate(beams)
    return np.asarray(100 * (b / b.sum(axis=1, keepdims=True)).mean(axis=0), dtype=np.float64)


def odometry_path_m(recording: Recording) -> float:
    """Path length of the odometry increments (what the MCL counts as travel)."""
    odo = np.asarray(recording.odometry[1:], dtype=np.float64)
    return float(np.hypot(odo[:, 0], odo[:, 1]).sum())


@dataclass(frozen=True)
class RunFacts:
    """What the episodes at the paper's crowd size show (means over them unless said otherwise).

    Attributes:
        estimates_per_run: the distinct numbers of estimates per run, sorted.
        median_estimates: their median.
        duration_s, contacts, push_m: simulated seconds, contacts and push per run.
        window_points: points in the far-point filter's window at an update.
        record_s, pass_s, reference_s: seconds of recording, of the far-point pass and of the reference pass per run.
        steps: steps (LIDAR scans) per run.
        odometry_excess_m: odometry path length beyond the true one, per run.
        cpu_s: CPU seconds of all tasks (every episode and replay).
        beam_pct: ``"raw"`` / ``"far"`` -> :func:`beam_pct` over all update steps.
    """

    estimates_per_run: tuple[int, ...]
    median_estimates: int
    duration_s: float
    contacts: float
    push_m: float
    window_points: float
    record_s: float
    pass_s: float
    reference_s: float
    steps: int
    odometry_excess_m: float
    cpu_s: float
    beam_pct: dict[str, Array]


def run_facts(episodes: Sequence[Episode], runs: Sequence[Run]) -> RunFacts:
    main = main_episodes(episodes)

    def mean(values: Sequence[float] | NDArray[np.int64]) -> float:
        return float(np.mean(values))

    excess = [odometry_path_m(ep.recording) - metrics.travelled(ep.recording.true_pose)[-1] for ep in main]
    return RunFacts(
        estimates_per_run=tuple(sorted({int(ep.update_steps.size) for ep in main})),
        median_estimates=int(np.median([ep.update_steps.size for ep in main])),
        duration_s=mean([ep.recording.time_s[-1] for ep in main]),
        contacts=mean([ep.contacts for ep in main]),
        push_m=mean([ep.push_m for ep in main]),
        window_points=mean(np.concatenate([ep.accumulated_points for ep in main])),
        record_s=mean([ep.record_s for ep in main]),
        pass_s=mean([ep.pass_s for ep in main]),
        reference_s=mean([ep.reference_s for ep in main]),
        steps=int(np.mean([ep.recording.steps for ep in main])),
        odometry_excess_m=mean(excess),
        cpu_s=sum(ep.cpu_s for ep in episodes) + sum(r.cpu_s for r in runs),
        beam_pct={k: beam_pct([ep.beams[k] for ep in main]) for k in ("raw", "far")},
    )


@dataclass(frozen=True)
class DensityRow:
    """One crowd size of the crowd-size sweep (``DENSITY_PARAMS``).

    ``raw`` / ``far``: against the truth; ``raw_ref`` / ``far_ref``: against the reference;
    ``reference``: the reference pose against the truth.
    """

    people: int
    raw: Stats
    far: Stats
    raw_on_wall_pct: float
    far_on_wall_pct: float
    raw_ref: Stats
    far_ref: Stats
    reference: Stats

    def variant(self, far: bool, against: Against) -> Stats:
        if against == "truth":
            return self.far if far else self.raw
        return self.far_ref if far else self.raw_ref


def density_rows(st: StatsTable, episodes: Sequence[Episode], st_ref: StatsTable) -> list[DensityRow]:
    pair = both(DENSITY_PARAMS)
    ref = reference_stats(episodes)
    rows = []
    for n in sorted({ep.task.crowd_size for ep in episodes}):
        eps = [ep for ep in episodes if ep.task.crowd_size == n]
        on_wall = {k: float(beam_pct([ep.beams[k] for ep in eps])[0]) for k in ("raw", "far")}
        rows.append(DensityRow(n, *pair_stats(st, pair, n), on_wall["raw"], on_wall["far"], *pair_stats(st_ref, pair, n), ref[n]))
    return rows


def first_failing(rows: Sequence[DensityRow], against: Against = VERDICT_MEASURE) -> dict[bool, int | None]:
    """Per variant (far points?), the first crowd size at which it stops working (None: none)."""
    out: dict[bool, int | None] = {}
    for far in (False, True):
        out[far] = next((r.people for r in rows if not r.variant(far, against).works), None)
    return out


@dataclass(frozen=True)
class NarrowHit:
    """Raw MCL at the narrowest hit of the full sweep against the wider ones."""

    hit_m: float
    raw_mean_m: float
    far_mean_m: float
    wider_min_m: float
    wider_max_m: float


def narrow_hit(plan: Plan, st: StatsTable) -> NarrowHit | None:
    """None unless the plan sweeps the narrowest hit and at least one other."""
    h = {round(x, 3): pair for x, pair in plan.hit_configs()}
    narrow = HITS[0]
    if narrow not in h or len(h) < 2:
        return None
    raw, far = pair_stats(st, h[narrow])
    wider = [st[pair[0].key, CROWD_SIZE].mean_m for x, pair in h.items() if x > narrow]
    return NarrowHit(narrow, raw.mean_m, far.mean_m, min(wider), max(wider))


@dataclass(frozen=True)
class EmptyRoom:
    """Both variants in the empty room (``DENSITY_PARAMS``), and the bias of their ranges on the walls."""

    raw_mean_m: float
    far_mean_m: float
    raw_wall_bias_m: float
    far_wall_bias_m: float


def empty_room(st: StatsTable, episodes: Sequence[Episode]) -> EmptyRoom | None:
    """None without empty-room episodes."""
    empty = [ep for ep in episodes if ep.task.crowd_size == 0]
    pair = both(DENSITY_PARAMS)
    if not empty or (pair[0].key, 0) not in st:
        return None
    raw, far = pair_stats(st, pair, 0)
    bias = {k: float(np.nanmean(np.concatenate([ep.wall_bias_m[k] for ep in empty]))) for k in ("raw", "far")}
    return EmptyRoom(raw.mean_m, far.mean_m, bias["raw"], bias["far"])


# ------------------------------------------------------------------------------------ results.json


def _fit_summary(fit: metrics.Consistency) -> dict[str, float]:
    """A run's NEES in results.json: its median, the share inside the 95 % region, the share without a covariance."""
    return {"nees_median": fit.nees_median, "inside_95": fit.inside_95, "covariance_missing": consistency.missing_share(fit)}


def results_data(plan: Plan, st: StatsTable, runs: Sequence[Run], episodes: Sequence[Episode], identity_m: float,
                 verdicts: Sequence[Mapping[str, Any]], st_ref: StatsTable,
                 verdicts_truth: Sequence[Mapping[str, Any]]) -> dict[str, Any]:  # fmt: skip
    """Everything ``results.json`` holds: the plan, the statistics (against the truth: ``stats``;
    against the reference: ``stats_vs_reference``; the reference against the truth:
    ``reference``), the NEES against the truth (``consistency``, ``reference_consistency``;
    and each run's), the verdicts (on the paper's measure, ``verdicts``; on the truth,
    ``verdicts_vs_truth``), every run's errors against both."""
    return {
        "plan": dataclasses.asdict(plan),
        "estimates_per_run": sorted({int(ep.update_steps.size) for ep in main_episodes(episodes)}),
        "identity_max_difference_m": identity_m,
        "verdict_measure": VERDICT_MEASURE,
        "stats": {f"{key}@{n}": dataclasses.asdict(s) for (key, n), s in st.items()},
        "stats_vs_reference": {f"{key}@{n}": dataclasses.asdict(s) for (key, n), s in st_ref.items()},
        "reference": {str(n): dataclasses.asdict(s) for n, s in reference_stats(episodes).items()},
        "consistency": {f"{key}@{n}": dataclasses.asdict(f) for (key, n), f in fit_table(runs).items()},
        "reference_consistency": {str(n): dataclasses.asdict(f) for n, f in reference_fits(episodes).items()},
        "verdicts": list(verdicts),
        "verdicts_vs_truth": list(verdicts_truth),
        "runs": [
            {
                "key": r.key,
                "seed": r.seed,
                "crowd_size": r.crowd_size,
                "errors_m": r.errors_m.tolist(),
                "ref_errors_m": r.ref_errors_m.tolist(),
                **_fit_summary(fit_of([r])),
            }
            for r in runs
        ],  # fmt: skip
        "episodes": [
            {
                "seed": ep.task.seed,
                "crowd_size": ep.task.crowd_size,
                "contacts": ep.contacts,
                "push_m": ep.push_m,
                "updates": int(ep.update_steps.size),
                "reference_errors_m": r.errors_m.tolist(),
                **{f"reference_{k}": v for k, v in _fit_summary(fit_of([r])).items()},
            }
            for ep, r in zip(episodes, reference_runs(episodes))
        ],  # fmt: skip
    }
