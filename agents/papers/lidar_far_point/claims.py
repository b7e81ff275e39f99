"""The paper's claims in words: each claim's text and how our evidence on it is stated, and the
verdict records of results.json.

The verdicts themselves (and the numbers they carry) are :mod:`.analysis`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from . import paper
from .analysis import ERROR_GROWTH, FLAT_SPREAD, VERDICT_MEASURE, Verdict
from .tables import fmt, value_set, works_pct


@dataclass(frozen=True)
class Claim:
    """A claim of the paper and how to state our evidence on it."""

    text: str
    evidence: Callable[[Mapping[str, Any]], str]


def _c1(n: Mapping[str, Any]) -> str:
    t = paper.SAMPLING_THRESHOLD
    return (
        f"raw MCL, mean over sampling < {t:g} vs >= {t:g}: error {n['error_below_m']:.3f} vs {n['error_from_m']:.3f} m, "
        f"failure rate {100 * n['failure_rate_below']:.1f} % vs {100 * n['failure_rate_from']:.1f} % of estimates. "
        f"Criterion: error up by > {100 * (ERROR_GROWTH - 1):.0f} % and failures up to >= {works_pct()} %."
    )


def _c2(n: Mapping[str, Any]) -> str:
    x0, x1 = n["samplings"]
    return (
        f"far points: error {n['far_error_min_m']:.3f}-{n['far_error_max_m']:.3f} m over sampling {x0:g}-{x1:g}, "
        f"failure rate <= {100 * n['far_failure_rate_max']:.1f} %; works at sampling {value_set(n['far_works_at'])}. "
        f"Criterion: works (< {works_pct()} % failures) everywhere and the largest mean error < {FLAT_SPREAD:g}x the smallest."
    )


def _c3(n: Mapping[str, Any]) -> str:
    return (
        f"lower error and no more failures at {n['better']} of {n['of']} sampling values >= {paper.SAMPLING_THRESHOLD:g} "
        f"(far/raw error ratio {n['far_raw_error_ratio']:.2f} averaged over them)."
    )


def _c4(n: Mapping[str, Any]) -> str:
    at = n["at_threshold"]
    extra = ""
    if at is not None:
        extra = (f" At hit {paper.HIT_THRESHOLD:g}: {at['failures']:.2f} failures per run of {at['estimates']} (paper: "
                 f"{paper.RAW_FAILURES_AT_HIT_THRESHOLD} of {paper.ESTIMATES}), {at['large_total']} estimates >= "
                 f"{paper.LARGE_FAIL_M:g} m in {at['runs']} runs.")  # fmt: skip
    return (
        f"raw MCL fails (>= {works_pct()} % of estimates) at hit {value_set(n['raw_fails_at'])}; "
        f"{n['raw_large_from_threshold']} estimates >= {paper.LARGE_FAIL_M:g} m at hit >= {paper.HIT_THRESHOLD:g}; median "
        f"heading error of those failures {fmt(n['failure_heading_deg'], '{:.0f}')} deg.{extra}"
    )


def _c5(n: Mapping[str, Any]) -> str:
    return (
        f"far points: {n['far_large']} estimates >= {paper.LARGE_FAIL_M:g} m and {n['far_failures']} >= {paper.FAIL_M:g} m over "
        f"all hit values and runs (raw: {n['raw_large']} and {n['raw_failures']})."
    )


def _c6(n: Mapping[str, Any]) -> str:
    note = " Raw MCL works at every value too, so there is no range to widen here." if n["raw_works_everywhere"] else ""
    return (
        f"working values: sampling raw {value_set(n['sampling_raw_works_at'])} vs far "
        f"{value_set(n['sampling_far_works_at'])}; hit raw {value_set(n['hit_raw_works_at'])} vs far "
        f"{value_set(n['hit_far_works_at'])} ({n['raw_works']} vs {n['far_works']} of {n['of']}).{note} The processing "
        f"gives the lower mean error at {n['far_lower_error']} of {n['of']} values."
    )


def _c7(n: Mapping[str, Any]) -> str:
    return f"raw MCL works at {n['raw_works']} of {n['of']} swept values; its lowest mean error {n['raw_lowest_error_m']:.3f} m."


CLAIMS: dict[str, Claim] = {
    "C1": Claim(f"Raw MCL's mean error and failures grow from sampling {paper.SAMPLING_THRESHOLD:g} up (Figs 7, 8).", _c1),
    "C2": Claim("With the far-point processing, error and failures stay low over the whole sampling range.", _c2),
    "C3": Claim(
        f"From sampling {paper.SAMPLING_THRESHOLD:g} up the processing gives a lower error and fewer failures than raw MCL.", _c3
    ),  # fmt: skip
    "C4": Claim(
        f"Raw MCL fails (> {paper.LARGE_FAIL_M:g} m, ~{paper.LARGE_FAIL_HEADING_DEG:g} deg off) from hit "
        f"{paper.HIT_THRESHOLD:g} up, and not below (Figs 9-11).",
        _c4,
    ),  # fmt: skip
    "C5": Claim("With the processing there is no large failure over the hit sweep.", _c5),
    "C6": Claim("The processing widens the range of MCL parameters that work (the paper's conclusion).", _c6),
    "C7": Claim("Raw MCL also has a parameter range with a small error in this setting (the paper's closing remark).", _c7),
}


def verdict_record(v: Verdict, against: str = VERDICT_MEASURE) -> dict[str, Any]:
    """A verdict for results.json: its data and its words, and the measure it was taken on."""
    claim = CLAIMS[v.claim_id]
    return {"id": v.claim_id, "claim": claim.text, "verdict": v.verdict, "against": against,
            "evidence": claim.evidence(v.numbers), "numbers": v.numbers}  # fmt: skip
