"""Number formatting for the report: missing values print as ``n/a``, never as ``nan``."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def pm(v: Sequence[float], digits: int = 0) -> str:
    """``"mean ± sd"`` of ``(mean, sd, ...)``."""
    if not np.isfinite(v[0]):
        return "n/a"
    return f"{v[0]:.{digits}f} ± {v[1]:.{digits}f}"


def num(v: float, fmt: str = "{:.0f}") -> str:
    """``v`` in ``fmt``, or ``n/a``."""
    return fmt.format(v) if np.isfinite(v) else "n/a"


def ratio(ours: float, paper: float) -> str:
    """``ours / paper`` to two decimals."""
    return f"{ours / paper:.2f}" if np.isfinite(ours) and paper > 0 else "n/a"


def versus(ours: float, paper: float) -> str:
    """``"3.6x the paper's"`` / ``"0.40x the paper's"``."""
    return f"{ours / paper:.2f}x the paper's" if np.isfinite(ours) and paper > 0 else "n/a"


def about(v: float, step: float = 0.5) -> str:
    """``v`` rounded to a multiple of ``step``, for "about ..." (0.44 -> ``"0.5"``)."""
    return f"{round(v / step) * step:g}"


def xy(x: float, y: float) -> str:
    """``"(5, 10)"``."""
    return f"({x:g}, {y:g})"


def pi_fraction(angle_rad: float) -> str:
    """``"pi/9"`` for ``pi / 9``."""
    return f"pi/{math.pi / angle_rad:.0f}"


def count_range(mean: float) -> str:
    """The whole numbers around a mean count: ``"3-4"`` for 3.57."""
    return f"{math.floor(mean)}-{math.ceil(mean)}"


def facing(theta_rad: float) -> str:
    """``"facing +x"`` for heading 0, else the heading in degrees."""
    axes = {0.0: "+x", 90.0: "+y", 180.0: "-x", -90.0: "-y"}
    deg = math.degrees(math.remainder(theta_rad, math.tau))
    return f"facing {axes[deg]}" if deg in axes else f"heading {deg:g} deg"


def field(size_m: Sequence[float]) -> str:
    """``"5 m"`` for a square field, else ``"5 m x 10 m"``."""
    w, h = size_m
    return f"{w:g} m" if w == h else f"{w:g} m x {h:g} m"


def and_list(items: Sequence[str]) -> str:
    """``"a, b and c"``."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]
