"""report.md and results.json, filled from the analysis and from the configs (no parameter restated by hand).

Every number in the prose comes from the runs (:mod:`.analysis`), the paper (:mod:`.paper`),
our set-up (:mod:`.experiment`) or the shipped world and localizer configs (:mod:`.world`).
One function per report section; :func:`write_report` puts them together. The tables' cells and
rows are :mod:`.tables`', the claims in words :mod:`.claims`'.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.common.util import jsonable, text_table
from agents.evaluate import consistency
from agents.papers.world_text import odometry_text

from . import experiment, paper, world
from .analysis import (
    VERDICT_MEASURE,
    Against,
    DensityRow,
    EmptyRoom,
    NarrowHit,
    RunFacts,
    Stats,
    StatsTable,
    Verdict,
    empty_room,
    first_failing,
    fit_table,
    narrow_hit,
    pair_stats,
    reference_fits,
    results_data,
)
from .claims import CLAIMS, verdict_record
from .experiment import Params, Plan
from .jobs import Episode, Run
from .tables import (
    CELL_COLUMNS,
    FIT_TAG,
    Lines,
    cell,
    fit_cells,
    fit_head,
    fit_rows,
    fmt,
    pair_rows,
    params_text,
    same_or_list,
    table_head,
    variant_head,
    works_pct,
)

# ------------------------------------------------------------------------------------ report sections


@dataclass(frozen=True)
class Context:
    """Everything the sections are filled from."""

    plan: Plan
    episodes: Sequence[Episode]
    runs: Sequence[Run]
    st: StatsTable
    facts: RunFacts
    verdicts: Sequence[Verdict]
    density: Sequence[DensityRow]
    figs: Mapping[str, Path]
    wall_s: float
    workers: int
    identity_m: float
    extraction: tuple[int, float]
    st_ref: StatsTable  # against the reference pose (``st``: against the truth)
    verdicts_truth: Sequence[Verdict]  # on the truth (``verdicts``: on the paper's measure)
    reference: Mapping[int, Stats]  # per crowd size, the reference pose against the truth


def header(c: Context) -> Lines:
    cpu, w = c.facts.cpu_s, c.workers
    return [
        "# LIDAR scan accumulation + far-point extraction in a crowd (Fujii et al.): reproduction",
        "",
        f"`crowdloc reproduce lidar-far-point{' --quick' if c.plan.quick else ''}` — {c.plan.seeds} seed(s) per point, "
        f"{len(c.episodes)} recorded episodes, {len(c.runs)} MCL runs; {c.wall_s:.0f} s wall with {w} worker(s), "
        f"{cpu:.0f} CPU seconds in the tasks (about {cpu / max(w, 1):.0f} s of wall time on {w} idle cores). "
        "docs/papers.md section B; the paper's Figs 7, 8, 10 and 11 are plots without printed values, so its claims are "
        "checked qualitatively, with the few numbers its text gives.",
        "",
    ]


def world_item() -> str:
    """The set-up's first item: the room, the queues, the LIDAR, the people (all from the world config)."""
    r, lidar = world.room(), world.lidar()
    q = world.queues()
    width, height = r.size_m
    return (
        f"- World `{experiment.ENV_ID}` ({width:g} m x {height:g} m room), {experiment.CROWD_SIZE} people in two queues at x = "
        f"{q.left_x_m:g} m and {q.right_x_m:g} m ({q.spacing_m:g} m apart, each stepping forward every {q.step_period_s:g} s, "
        f"the head walking to the end of the other queue), a UTM-30LX-like LIDAR ({math.degrees(lidar.fov_rad):g} deg, "
        f"{lidar.beams} beams, {lidar.max_range_m:g} m, {100 * lidar.range_std_m:g} cm noise) at {1 / r.dt_s:g} Hz and "
        f"{lidar.height_m:g} m (the paper's {paper.LIDAR_HEIGHT_M:g} m); the people have two legs, a torso and a head "
        f"(`envs/bodies.py`), so the scan plane cuts their legs: {world.legs_text()}. {room_text()}"
    )


def moved_text() -> str:
    """Where the localizers' map is wrong: each moved piece and by how much."""
    moved = world.moved_furniture()
    return " and ".join(f"the {name} {100 * d:.0f} cm from where it stands" for name, d in moved) if moved else "nothing moved"


def room_text() -> str:
    """The room beyond its four walls, and what the localizers' map gets wrong (from the world config)."""
    r, h = world.room(), world.lidar().height_m
    unseen = world.furniture_text(h, seen=False)
    cut = "every piece" if unseen == "none" else f"all but {unseen}"
    return (
        f"Besides its four walls the room has {len(r.walls)} more wall segments (an open door, a bevelled corner) and "
        f"furniture with heights: {world.furniture_text()}. The localizers' map has {moved_text()} (`map_offset_m`), and "
        f"each LIDAR's map is cut at its height (at {h:g} m it holds {cut})."
    )


def beams_text(stride: int) -> str:
    """Which of the LIDAR's beams the MCL weighs."""
    beams = world.lidar().beams
    return f"all {beams} beams" if stride == 1 else f"every {stride}th of the {beams} beams ({len(range(0, beams, stride))})"


def mcl_item() -> str:
    """The set-up's MCL item (from ``configs/localizers/mcl_lidar.yaml`` and ``far_point_mcl.yaml``)."""
    m, far = world.mcl_defaults(), world.far_point_defaults()
    f = far.filter
    window = (
        "; its reported covariance adds a third of the window's odometry noise at each fix (`window_error`, ours: "
        "the fix inherits the error of the odometry that placed the points; the estimates are the same without it)"
        if far.window_error
        else ""
    )
    ess = m.resample_ess_fraction
    resampling = "resampling after every update" if ess >= 1.0 else f"resampling when the ESS falls below {ess:g} of the set"
    return (
        f"- MCL (`mcl_lidar`, shipped defaults otherwise): {m.n_particles} particles, odometry motion model with alphas = "
        f"sampling x ({', '.join(f'{a:g}' for a in m.alphas_base)}) (the base alphas are ours: the paper does not give "
        f"them), {m.model.replace('_', ' ')} model z_hit {m.z_hit:g}, z_short {m.z_short:g}, z_max {m.z_max:g}, z_rand "
        f"{m.z_rand:g}, lambda_short {m.lambda_short:g}, {beams_text(m.beam_stride)}; {resampling}. Far points "
        f"(`far_point_mcl`): scans accumulated over the last {f.travel_m:g} m of travel by odometry, "
        f"{math.degrees(f.bin_width_rad):g} deg bins{window}."
    )


def reference_params_text() -> str:
    """The reference MCL's parameters in words: the shipped ones with ``REFERENCE_MCL_PARAMS`` on top."""
    p = dataclasses.replace(world.mcl_defaults(), **dict(experiment.REFERENCE_MCL_PARAMS))
    which = (
        "its shipped parameters"
        if not experiment.REFERENCE_MCL_PARAMS
        else "its shipped parameters with " + ", ".join(f"{k} {v}" for k, v in experiment.REFERENCE_MCL_PARAMS)
    )
    return (
        f"{which} (`{world.params_file('mcl_lidar')}`: the {p.model.replace('_', ' ')} model, the paper's MCL; not the "
        f"likelihood field the file offers as `model`), sampling {p.sampling:g}, hit {p.hit_std_m:g} m, {p.n_particles} "
        f"particles, {beams_text(p.beam_stride)}"
    )


def reference_item(c: Context) -> str:
    """The set-up's item on the reference pose: the second LIDAR and its MCL, and its own error against the truth."""
    h = paper.REFERENCE_LIDAR_HEIGHT_M
    ref = c.reference.get(experiment.CROWD_SIZE)
    walls = "the walls, the door and the bevelled corner" if world.room().wall_height_m > h else "no wall"
    own = ""
    if ref is not None:
        own = (
            f" Its own error against the truth at {experiment.CROWD_SIZE} people: {fmt(ref.mean_m)} ± {fmt(ref.sd_m)} m "
            f"(median {fmt(ref.median_m)}, largest {fmt(ref.max_m)} m; {ref.failures_total} of its {ref.runs * ref.estimates} "
            f"estimates >= {paper.FAIL_M:g} m off): the yardstick's own error, which enters every error measured against it "
            "(per crowd size in the crowd-size table)."
        )
    return (
        f"- Reference (the paper's): a second LIDAR at {h:g} m above the crowd (`{experiment.REFERENCE_SENSOR}`, added with "
        "the env's `sensors` keyword: the room LIDAR's field of view, beams, range and noise at that height), localized by "
        f"`mcl_lidar` with {reference_params_text()}, on the experiment's update schedule (it weighs the same steps as the "
        f"variants), from the known start pose, with its own random numbers. Its map is cut at {h:g} m: {walls}, "
        f"{world.furniture_text(h)}; without {world.furniture_text(h, seen=False)}. Of the people it sees the tallest "
        f"heads only.{own} Both variants start from the known start pose too (the paper's MCL tracked from a known pose)."
    )


def metrics_item() -> str:
    """The set-up's item on the metrics: both yardsticks, failures, what works, which verdict."""
    return (
        "- Metrics at each estimate: the position error against the reference pose (the paper's measure) and against "
        "the simulator's true pose (ours); per configuration the mean and sd over all estimates of all runs (the paper: "
        f"over its one run's {paper.ESTIMATES}); failures = estimates >= {paper.FAIL_M:g} m from the reference, as the "
        f"paper defines them (and, ours, >= {paper.FAIL_M:g} m from the truth), counted per run; large failures >= "
        f"{paper.LARGE_FAIL_M:g} m. A configuration *works* when fewer than {works_pct()} % of its estimates fail (ours, "
        f"fixed before the evaluation runs; a pilot on seeds {experiment.PILOT_SEEDS[0]}-{experiment.PILOT_SEEDS[1]} set "
        f"the side of the square and the configuration of the crowd-size sweep). The verdicts on the paper's claims are "
        f"taken on its measure (against the {VERDICT_MEASURE}), the truth-based verdict beside each where it differs."
    )


def setup_section(c: Context) -> Lines:
    f, laps = c.facts, c.plan.laps
    per_run_m = experiment.perimeter_m() * laps
    points, extraction_s = c.extraction
    room = world.room()
    return [
        "## Set-up",
        "",
        world_item(),
        f"- Path (ours: the paper gives no size): an open-loop square of side {experiment.SIDE_M} m centred in the room, "
        f"counter-clockwise from {tuple(round(v, 2) for v in experiment.start_pose()[:2])} facing +x, {laps} lap(s) at "
        f"{paper.SPEED_MPS} m/s, turns in place at {experiment.TURN_RATE_RPS} rad/s (`agents.experiments.scenarios.square_driver`); "
        f"{experiment.perimeter_m():.1f} m per lap, {f.duration_s:.0f} s per run. The square leaves "
        f"{world.queue_gap_m(experiment.CENTER_XY, experiment.SIDE_M):.2f} m between the robot's and the queued people's "
        "bodies.",
        f"- The MCL weighs a scan every {paper.UPDATE_TRAVEL_M} m of travel (`update_min_travel_m`; turning in place does not "
        f"trigger an update: `update_min_rotation_rad` = {experiment.UPDATE_MIN_ROTATION_RAD / math.pi:g} pi): "
        f"**{'/'.join(map(str, f.estimates_per_run))} estimates per run** (paper: {paper.ESTIMATES}; {per_run_m:.1f} m / "
        f"{paper.UPDATE_TRAVEL_M} m = {per_run_m / paper.UPDATE_TRAVEL_M:.1f}, plus the one at the start, plus what odometry "
        "noise adds: see the differences below).",
        reference_item(c),
        f"- The robot at the world's {room.robot.mass_kg:g} kg: the queue heads walking across the room give way to it "
        f"(`queues.give_way`: they curve around it, {world.queues().give_way_margin_m:g} m clear), as the paper's people "
        f"did; {f.contacts:.1f} contacts per run on average, {f.push_m * 100:.1f} cm of push left per run.",
        mcl_item(),
        "- Every (seed, crowd size) episode is recorded once and replayed into every configuration (the localizers share one "
        "generator seed per episode, so the variants see the same random numbers). The far-point scans come from one real "
        f"`far_point_mcl` pass per episode ({params_text(experiment.PASS_PARAMS)}); replaying `mcl_lidar` on them "
        f"reproduces that pass's estimates with a largest difference of {c.identity_m:g} m "
        f"(`agents.papers.lidar_far_point.jobs`). The filter held {f.window_points:,.0f} points on average at an update (paper: "
        f"~{paper.POINTS_PER_WINDOW:,}); one extraction over {points:,} points takes {1000 * extraction_s:.1f} ms here (paper: "
        f"{paper.EXTRACTION_S} s for ~{paper.POINTS_PER_WINDOW:,}). Per run: recording {f.record_s:.1f} s, far-point pass "
        f"{f.pass_s:.1f} s (accumulating all {f.steps} scans, extracting and weighing at each update), reference pass "
        f"{f.reference_s:.1f} s.",
        metrics_item(),
        "",
    ]


def sweep_sections(c: Context) -> Lines:
    """The sampling sweep (Figs 7, 8) and the hit sweep (Figs 10, 11), tables and figures."""
    lines = [
        "## Sampling parameter (Figs 7 and 8)",
        "",
        f"{world.mcl_defaults().n_particles} particles, hit {experiment.SAMPLING_SWEEP_HIT_M:g} m. Cells, against the "
        "reference pose (the paper's measure) and against the true pose (ours): mean ± sd of the position error over all "
        f"estimates; mean failures per run (total over the runs, of them >= {paper.LARGE_FAIL_M:g} m); runs with at least "
        "one failure.",
        "",
        *table_head("sampling"),
        *pair_rows(c.plan.sampling_configs(), c.st, c.st_ref),
        "",
        *fit_rows("sampling", c.plan.sampling_configs(), c.runs),
        "",
        f"![Fig. 7]({c.figs['sampling_error'].name})",
        f"![Fig. 8]({c.figs['sampling_failures'].name})",
        "",
        f"## Hit sd at sampling {paper.HIT_SWEEP_SAMPLING} (Figs 10 and 11)",
        "",
        *table_head("hit [m]"),
        *pair_rows(c.plan.hit_configs(), c.st, c.st_ref),
        "",
        *fit_rows("hit [m]", c.plan.hit_configs(), c.runs),
        "",
        f"![Fig. 10]({c.figs['hit_error'].name})",
        f"![Fig. 11]({c.figs['hit_failures'].name})",
        "",
    ]
    if "trajectories" in c.figs:
        lines += [f"![trajectories]({c.figs['trajectories'].name})", ""]
    return lines


def claims_section(c: Context) -> Lines:
    lines = [
        "## The paper's claims, one by one",
        "",
        f"The verdicts are taken on the paper's measure, the error against the {VERDICT_MEASURE} pose (its claims are about "
        "that measure); the verdict on the error against the true pose stands beside it, with its numbers where it differs.",
        "",
        f"| # | claim | verdict (vs {VERDICT_MEASURE}) | vs truth | our numbers (vs {VERDICT_MEASURE}) |",
        "|---|---|---|---|---|",
    ]
    truth = {v.claim_id: v for v in c.verdicts_truth}
    for v in c.verdicts:
        claim = CLAIMS[v.claim_id]
        t = truth.get(v.claim_id)
        if t is None or t.verdict == v.verdict:
            beside, extra = "same", ""
        else:
            beside, extra = f"*{t.verdict}*", f" Against the truth: {claim.evidence(t.numbers)}"
        lines.append(f"| {v.claim_id} | {claim.text} | **{v.verdict}** | {beside} | {claim.evidence(v.numbers)}{extra} |")
    return [*lines, ""]


def scan_section(c: Context) -> Lines:
    """Fig. 5: where the beams of the raw and the far-point scans end."""

    def shares(pct: np.ndarray) -> str:
        return " | ".join(f"{v:.1f} %" for v in pct)

    lines = [
        "## What the processing does to the scan (Fig. 5)",
        "",
        "Beams of the scan weighed at each update compared with the empty room's ranges from the true pose, cast against "
        f"the room's static segments where they stand at the LIDAR's height (not the localizers' map, which has "
        f"{moved_text()}) ({experiment.CROWD_SIZE} people, all update steps of all runs): on the wall (within "
        f"{experiment.WALL_TOL_M:g} m), short of it (a person), past it, at maximum range (for far points: an empty bin).",
        "",
        "| scan | on the wall | short (people) | past the wall | max range / empty |",
        "|---|---:|---:|---:|---:|",
        f"| raw | {shares(c.facts.beam_pct['raw'])} |",
        f"| far points | {shares(c.facts.beam_pct['far'])} |",
        "",
    ]
    if "far_points" in c.figs:
        lines += [f"![Fig. 5]({c.figs['far_points'].name})", ""]
    return lines


def amcl_label(name: str, params: Params) -> str:
    """The AMCL-like rows' labels, from their parameters."""
    p = dict(params)
    if name == "amcl_like":
        return (f"AMCL-like: {p['model'].replace('_', ' ')}, z_hit {p['z_hit']:g}, z_rand {p['z_rand']:g}, "
                f"sigma_hit {p['hit_std_m']:g}, sampling {p['sampling']:.1f}")  # fmt: skip
    alphas = same_or_list(p["sampling"] * a for a in world.mcl_defaults().alphas_base)
    beams = len(range(0, world.lidar().beams, p.get("beam_stride", 1)))
    return f"ROS amcl defaults: the same, sampling {p['sampling']:.1f} (odom alphas {alphas}), {beams} beams"


def amcl_section(c: Context) -> Lines:
    rows = [(amcl_label(name, pair[0].params), pair) for name, pair in c.plan.amcl_configs()]
    return [
        "## Beyond the paper",
        "",
        f"### (a) AMCL-like measurement model ({experiment.CROWD_SIZE} people)",
        "",
        *table_head("configuration"),
        *pair_rows(rows, c.st, c.st_ref),
        "",
        *fit_rows("configuration", rows, c.runs),
        "",
        "The likelihood field scores each beam's end point by its distance to the nearest wall and ignores what lies "
        "between; a beam ending on a person scores that person's distance to the wall, floored by z_rand over the "
        "maximum range, where the beam model has its short-reading term.",
        "",
    ]


def density_section(c: Context) -> Lines:
    lines = [
        f"### (b) Crowd size ({experiment.density_note()})",
        "",
        f"| people | {variant_head('MCL only')} | {variant_head('+ far points')} | raw beams on the wall "
        "| far-point beams on the wall | reference vs truth: error [m] | reference: failures / run (total) |",
        "|---:|" + "---:|" * (2 * CELL_COLUMNS + 4),
    ]
    for r in c.density:
        ref = r.reference
        lines.append(
            f"| {r.people} | {cell(r.raw_ref, r.raw)} | {cell(r.far_ref, r.far)} | {r.raw_on_wall_pct:.1f} % | "
            f"{r.far_on_wall_pct:.1f} % | {fmt(ref.mean_m)} ± {fmt(ref.sd_m)} | {ref.failures:.2f} ({ref.failures_total}) |"
        )
    most = c.density[-1].people
    fits, ref_fits = fit_table(c.runs), reference_fits(c.episodes)
    pair = experiment.both(experiment.DENSITY_PARAMS)
    fit_lines = [
        f"| people {FIT_TAG} | {fit_head('MCL only')} | {fit_head('+ far points')} | {fit_head('reference')} |",
        "|---:|" + "---:|" * 9,
        *(f"| {r.people} | " + " | ".join(fit_cells(v.localizer, fits[v.key, r.people]) for v in pair)
          + f" | {fit_cells(experiment.REFERENCE_LOCALIZER, ref_fits[r.people])} |" for r in c.density),
    ]  # fmt: skip

    def starts(against: Against) -> str:
        first = first_failing(c.density, against)
        return "; ".join(
            f"{experiment.VARIANTS[f]}: {first[f] if first[f] is not None else f'none up to {most}'}" for f in (False, True)
        )

    return [
        *lines,
        "",
        *fit_lines,
        "",
        consistency.legend(),
        "",
        f"Where each variant starts failing (first crowd size at which >= {works_pct()} % of the estimates fail), against "
        f"the reference: {starts('reference')}; against the truth: {starts('truth')}.",
        "",
        f"![crowd size: error]({c.figs['density_error'].name})",
        f"![crowd size: failures]({c.figs['density_failures'].name})",
        "",
    ]


def accuracy_notes(narrow: NarrowHit | None, empty: EmptyRoom | None) -> Lines:
    """What sets the error floor of each variant, from our numbers."""
    out = []
    if narrow is not None:
        h = narrow.hit_m
        out.append(
            f"- Hit sd, not sampling, sets raw MCL's error here (against the truth): {narrow.raw_mean_m:.3f} m at hit {h:g} against "
            f"{narrow.wider_min_m:.3f}-{narrow.wider_max_m:.3f} m above it. A hit Gaussian about as wide as the queue's "
            f"offset from its wall lets the many beams on the queue pull the estimate toward it; at {h:g} m they fall to "
            f"the short-reading term. (Far points at hit {h:g}: {narrow.far_mean_m:.3f} m.)"
        )
    if empty is not None:
        out.append(
            f"- The processing has a cost of its own: in the empty room it is "
            f"{'less' if empty.far_mean_m > empty.raw_mean_m else 'no less'} accurate than the raw scan (against the truth: "
            f"{empty.far_mean_m:.3f} against {empty.raw_mean_m:.3f} m). The far point of a bin is the largest of the many "
            f"noisy returns of one wall patch collected over {world.far_point_defaults().filter.travel_m:g} m, so "
            f"far-point ranges on the walls are biased outward by {1000 * empty.far_wall_bias_m:.0f} mm on average (raw "
            f"scan: {1000 * empty.raw_wall_bias_m:+.1f} mm) at the LIDAR's {100 * world.lidar().range_std_m:g} cm noise."
        )
    return out


def people_item(c: Context) -> str:
    """The differences' item on the queued people (sizes from the world config)."""
    spacing = world.queues().spacing_m
    raw, far = c.facts.beam_pct["raw"], c.facts.beam_pct["far"]
    return (
        f"- People: the scan plane cuts their legs ({world.legs_text()}), queued {spacing:g} m apart "
        f"{world.queue_wall_offset_m():g} m in front of the side walls, so the wall behind a queue shows between legs and "
        f"between people. {far[1]:.0f} % of the far-point scan's beams fall short of the wall against {raw[1]:.0f} % of the "
        "raw scan's (walking people and the people near the robot are removed; the standing queues' legs stay)."
    )


def differences_section(c: Context) -> Lines:
    f = c.facts
    per_corner = f.odometry_excess_m / (len(experiment.corners()) * c.plan.laps)
    lines = [
        "## Differences from the paper, and why",
        "",
        f"- Estimates per run: {f.median_estimates} against the paper's {paper.ESTIMATES}. The MCL counts travel as the path "
        "length of the odometry increments, and the odometry's translation noise while turning in place adds "
        f"{100 * per_corner:.0f} cm per corner ({f.odometry_excess_m:.2f} m per run); our {experiment.perimeter_m():g} m square "
        "was chosen for the room, not to match the count.",
    ]
    h_pts = dict(c.plan.hit_configs())
    if paper.HIT_THRESHOLD in h_pts:
        raw, far = pair_stats(c.st, h_pts[paper.HIT_THRESHOLD])
        lines.append(
            f"- Hit {paper.HIT_THRESHOLD:g}: raw MCL {raw.failures:.2f} failures per run of {raw.estimates} "
            f"({raw.failures_total} in {raw.runs} runs, {raw.large_total} of them >= {paper.LARGE_FAIL_M:g} m) against the "
            f"paper's {paper.RAW_FAILURES_AT_HIT_THRESHOLD} of {paper.ESTIMATES} (> {paper.LARGE_FAIL_M:g} m each); far points "
            f"{far.failures:.2f} per run (paper: {paper.FAR_FAILURES_AT_HIT_THRESHOLD})."
        )
    lines += [
        people_item(c),
        failure_mode_item(),
        f"- The base alphas ({same_or_list(world.mcl_defaults().alphas_base)} each) are ours (the paper gives only the "
        "multiplier), and so is the odometry noise; the sampling value at which raw MCL degrades depends on both.",
        *accuracy_notes(narrow_hit(c.plan, c.st), empty_room(c.st, c.episodes)),
        reference_difference_item(c),
        f"- We average several runs per value where the paper shows one run of {paper.ESTIMATES} estimates, so its failure "
        "counts carry a run-to-run spread of about the size of the counts.",
        "",
    ]
    return lines


def failure_mode_item() -> str:
    """The differences' item on what the room and the odometry are like (from the world config)."""
    r = world.room()
    return (
        f"- The room and the robot: besides its four walls the room has {len(r.walls)} wall segments and "
        f"{len(r.furniture)} pieces of furniture, and the map has {moved_text()}. The odometry has {odometry_text(world.odometry(), r.robot)}: the "
        "systematic errors and the slip are motion it misreads, pushes by contacts motion it misses. The robot tracks "
        "from the known start pose (the paper's did too), so a filter only fails by losing track on the way."
    )


def reference_difference_item(c: Context) -> str:
    """The differences' item on the yardstick: ours measures against both, and how far apart they are."""
    ref = c.reference.get(experiment.CROWD_SIZE)
    pair = experiment.both(experiment.DENSITY_PARAMS)
    own = ""
    if ref is not None and (pair[0].key, experiment.CROWD_SIZE) in c.st:
        raw, far = pair_stats(c.st, pair)
        raw_ref, far_ref = pair_stats(c.st_ref, pair)
        own = (
            f" Here the reference is {fmt(ref.mean_m)} m off the truth on average at {experiment.CROWD_SIZE} people; at "
            f"{params_text(experiment.DENSITY_PARAMS)} raw MCL measures {fmt(raw_ref.mean_m)} m against it and "
            f"{fmt(raw.mean_m)} m against the truth, far points {fmt(far_ref.mean_m)} and {fmt(far.mean_m)} m."
        )
    return (
        "- Yardstick: like the paper we measure against MCL on the LIDAR above the crowd, whose own error enters every "
        "error against it (an error against the reference is neither an upper nor a lower bound on the error against the "
        f"truth), and beside it against the true pose, which the paper did not have.{own}"
    )


def parameters_section(c: Context) -> Lines:
    files = ", ".join(f"`{world.params_file(name)}`" for name in ("mcl_lidar", "far_point_mcl"))
    return [
        "## Parameters",
        "",
        f"Experiment-specific settings (nothing in `configs/` changed): the update schedule (every {paper.UPDATE_TRAVEL_M:g} m, "
        f"no update on turns), the path, the reference LIDAR (`{experiment.REFERENCE_SENSOR}` at "
        f"{paper.REFERENCE_LIDAR_HEIGHT_M:g} m, through the env's `sensors` keyword), and the swept `sampling` / "
        f"`hit_std_m` / model parameters. All other MCL and filter parameters are the shipped defaults ({files}). Per-run "
        "numbers: `results.json` beside this report.",
        "",
    ]


SECTIONS: tuple[Callable[[Context], Lines], ...] = (
    header,
    setup_section,
    sweep_sections,
    claims_section,
    scan_section,
    amcl_section,
    density_section,
    differences_section,
    parameters_section,
)


# ------------------------------------------------------------------------------------ writing


def summary_text(plan: Plan, st: StatsTable, verdicts: Sequence[Verdict], st_ref: StatsTable,
                 verdicts_truth: Sequence[Verdict]) -> str:  # fmt: skip
    """Both sweeps (against the reference and the truth) and the verdicts for stdout, as aligned tables."""
    tables = []
    for name, points in (("sampling", plan.sampling_configs()), ("hit", plan.hit_configs())):
        head = [name]
        for v in ("raw", "far"):
            head += [f"{v}: error vs ref m", f"{v}: fail/run vs ref", f"{v}: error vs truth m", f"{v}: fail/run vs truth"]
        cells = []
        for x, pair in points:
            row = [f"{x:g}"]
            for ref, truth in zip(pair_stats(st_ref, pair), pair_stats(st, pair)):
                for s in (ref, truth):
                    row += [f"{fmt(s.mean_m)} ± {fmt(s.sd_m)}", f"{s.failures:.2f}"]
            cells.append(row)
        tables.append(text_table(head, cells, align="r" * len(head)))  # the swept value, then numbers
    on_truth = {v.claim_id: v.verdict for v in verdicts_truth}
    claims = [[v.claim_id, v.verdict, on_truth.get(v.claim_id, "n/a"), CLAIMS[v.claim_id].text] for v in verdicts]
    tables.append(text_table(["claim", f"verdict (vs {VERDICT_MEASURE})", "vs truth", "the paper's claim"], claims, align="llll"))
    return "\n\n".join(tables)


def write_report(out: Path, c: Context) -> Path:
    """Write report.md (every section) and results.json into ``out``; return the report."""
    out.mkdir(parents=True, exist_ok=True)
    lines = [line for section in SECTIONS for line in section(c)]
    summary = results_data(c.plan, c.st, c.runs, c.episodes, c.identity_m, [verdict_record(v) for v in c.verdicts],
                           c.st_ref, [verdict_record(v, "truth") for v in c.verdicts_truth])  # fmt: skip
    (out / "results.json").write_text(json.dumps(jsonable(summary), indent=1, allow_nan=False))
    report = out / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return report
