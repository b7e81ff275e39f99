"""Former home of the paper reproductions, now :mod:`agents.papers` (``EXPERIMENTS`` is re-exported)."""

from __future__ import annotations

from agents.papers import EXPERIMENTS

__all__ = ["EXPERIMENTS"]
