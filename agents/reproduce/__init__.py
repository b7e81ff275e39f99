"""Paper reproductions (moved to :mod:`agents.papers`; ``EXPERIMENTS`` is re-exported from there)."""

from __future__ import annotations

from agents.papers import EXPERIMENTS

__all__ = ["EXPERIMENTS"]
