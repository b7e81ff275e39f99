"""A benchmark run's journal, ``episodes.jsonl`` in ``--out``: every scored episode, written the moment it finishes.

The full protocol takes hours on a small machine; a run that is killed or stopped
keeps what it finished, and ``crowdloc benchmark --resume`` with the same
options and ``--out`` plays only the rest, then writes the same tables as an uninterrupted run
(the scores are put back in the plan's order; the update cost, a timing, is the one exception).
It is :class:`agents.evaluate.journal.Journal` (eval's format) holding :class:`EpisodeScore` s
keyed by world and cell, under a header that records the plan (:func:`plan_record`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Hashable
from pathlib import Path
from typing import Any

from agents.benchmark.protocol import crowdloc_version, protocol_digest
from agents.benchmark.run import BenchmarkPlan, EpisodeScore
from agents.common.util import jsonable
from agents.evaluate.journal import JOURNAL_NAME, Journal

__all__ = ["JOURNAL_NAME", "ScoreJournal", "plan_record"]


def plan_record(plan: BenchmarkPlan) -> dict[str, Any]:
    """What a resumed run must match: the protocol (name, digest, version), quick or not, the
    plug-ins and each world's localizers, policies, crowd sizes and episode length.

    Not the seed count: the seeds are a prefix of the protocol's, and a run plays them seed by seed,
    so a run stopped after ``N`` seeds can be finished with ``--seeds N --resume`` (the journal's
    later episodes are kept and not used) or carried on to more seeds."""
    return {
        "protocol": plan.protocol.name,
        "protocol_digest": protocol_digest(plan.protocol),
        "crowdloc_version": crowdloc_version(),
        "quick": plan.quick,
        "plugins": list(plan.plugins),
        "worlds": {
            w.env_id: {
                "localizers": list(w.localizers),
                "policies": list(w.policies),
                "crowd_sizes": list(w.world.crowd_sizes),
                "episode_steps": w.spec.episode_steps,
            }  # fmt: skip
            for w in plan.worlds
        },
    }


class ScoreJournal(Journal[EpisodeScore]):
    """``crowdloc benchmark``'s journal: its scored episodes, keyed by (world, cell)."""

    KIND = "crowdloc benchmark journal"
    ITEM = EpisodeScore
    RUN = "benchmark"

    @staticmethod
    def key(item: EpisodeScore) -> Hashable:
        return item.key

    @staticmethod
    def readable(item: EpisodeScore) -> dict[str, Any]:
        return {"world": item.env_id, **dataclasses.asdict(item.cell), "values": jsonable(dict(item.values)),
                "update_ms": jsonable(item.update_ms)}  # fmt: skip

    @classmethod
    def start(cls, path: Path, plan: BenchmarkPlan) -> ScoreJournal:
        """A new journal for ``plan`` at ``path``."""
        journal: ScoreJournal = cls._start(path, plan_record(plan))
        return journal

    @classmethod
    def resume(cls, path: Path, plan: BenchmarkPlan) -> ScoreJournal:
        """The journal of an interrupted run of the same ``plan`` (:meth:`Journal._resume`)."""
        journal: ScoreJournal = cls._resume(path, plan_record(plan))
        return journal
