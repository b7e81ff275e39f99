"""Whether a localizer's reported covariance is honest, as the tables show it (NEES, inside the 95 % region).

The numbers are :mod:`agents.evaluate.metrics`' (:func:`~agents.evaluate.metrics.pose_nees`,
:func:`~agents.evaluate.metrics.consistency`); this module adds what the reports share around them:
whether a localizer has a covariance to score (``LocalizerSpec.covariance``), the per-step
NEES of a run that respects it, the cells of a table and the legend under it. Light on
purpose (numpy and the registry only): the reproductions' workers import it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

import agents.evaluate.metrics as metrics

#: what the tables show for a consistency metric of a localizer that reports no covariance
NO_COVARIANCE = "no covariance"
#: the pose's degrees of freedom (x, y, heading): the NEES of the reports is the 3-dof one
POSE_DOF = 3


def reports_covariance(localizer: str) -> bool:
    """Whether ``localizer``'s covariance is its own measure of uncertainty (``LocalizerSpec.covariance``)."""
    from localizers.registry import spec

    return spec(localizer).covariance


def run_nees(localizer: str, estimates: ArrayLike, truth: ArrayLike, covariances: ArrayLike) -> NDArray[np.float64]:
    """``(T,)`` 3-dof pose NEES of a run of ``localizer`` (:func:`agents.evaluate.metrics.pose_nees`).

    All NaN for a localizer that reports no covariance (:func:`reports_covariance`): its
    covariance is no measure to score.
    """
    e = np.asarray(estimates, dtype=np.float64).reshape(-1, 3)
    if not reports_covariance(localizer):
        return np.full(e.shape[0], np.nan)
    return metrics.pose_nees(e, truth, covariances, dof=POSE_DOF)


def missing_share(fit: metrics.Consistency) -> float:
    """Share of the steps asked for without a usable covariance (none, not finite, or a negative variance).

    :func:`agents.evaluate.metrics.consistency` leaves them out of the NEES median and the inside-95 % share,
    so a large share here means those two describe only part of the run. (A singular covariance,
    a collapsed particle set, is usable: its NEES is ``inf``, outside the region.)
    """
    total = fit.steps + fit.excluded
    return fit.excluded / total if total else math.nan


def consistent_median() -> float:
    """The NEES median of a consistent localizer (the chi-square median, 3 dof: 2.37)."""
    return metrics.chi2_quantile(0.5, POSE_DOF)


def legend() -> str:
    """The one-line legend under a table of NEES medians and shares inside the 95 % region."""
    return (
        f"NEES: pose error squared over the reported covariance (x, y, heading; {POSE_DOF} dof) over the steps with a "
        f"pose; inside 95 %: share of them with NEES <= {metrics.chi2_quantile(0.95, POSE_DOF):.2f}. Consistent: median "
        f"about {consistent_median():.2f}, inside about 95 %; a much larger median: overconfident (the covariance is too "
        f"small), much smaller: cautious (too large); a singular covariance (a collapsed particle set) claims "
        f"certainty and counts as outside (NEES inf); steps without a usable covariance are left out (their share: "
        f"covariance_missing in results.json); {NO_COVARIANCE}: the localizer reports none."
    )


def nees_text(value: float) -> str:
    """A NEES value in about three significant digits, without an exponent: 0.038, 2.37, 65.3, 523."""
    if abs(value) < 0.1:
        return f"{value:.2g}"
    return f"{value:.2f}" if abs(value) < 10 else f"{value:.1f}" if abs(value) < 100 else f"{value:.0f}"


def cells(covariance: bool, nees_median: float, inside_95: float) -> tuple[str, str]:
    """The NEES median and inside-95 % cells of a table row, or :data:`NO_COVARIANCE` twice.

    ``covariance``: whether the row's localizer reports one (:func:`reports_covariance`).
    """
    if not covariance:
        return NO_COVARIANCE, NO_COVARIANCE
    median = nees_text(nees_median) if not math.isnan(nees_median) else "n/a"  # inf: a collapsed set's claim
    inside = f"{100 * inside_95:.0f} %" if math.isfinite(inside_95) else "n/a"
    return median, inside


def pooled(nees: Sequence[ArrayLike], masks: Sequence[ArrayLike]) -> metrics.Consistency:
    """:func:`agents.evaluate.metrics.consistency` over the masked steps of several runs together (all seeds' steps)."""
    if len(nees) != len(masks):
        raise ValueError(f"pooled: {len(nees)} NEES series but {len(masks)} masks")
    if not nees:
        return metrics.consistency(np.zeros(0), POSE_DOF)
    values = np.concatenate([np.asarray(v, dtype=np.float64).reshape(-1) for v in nees])
    return metrics.consistency(values, POSE_DOF, np.concatenate([np.asarray(m, dtype=bool).reshape(-1) for m in masks]))
