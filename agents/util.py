"""Small helpers shared by the command-line tools: argparse types and JSON conversion."""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1, with a one-line error naming the bad text."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def jsonable(o: Any) -> Any:
    """Plain JSON values: mappings and sequences recursively, arrays to lists, numpy scalars
    to Python ones, non-finite floats to None, anything else to its ``str``."""
    if isinstance(o, Mapping):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return jsonable(o.tolist())
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, (np.integer, np.bool_)):
        return o.item()
    if isinstance(o, (int, bool, str)) or o is None:
        return o
    return str(o)
