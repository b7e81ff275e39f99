"""The run's journal, ``episodes.jsonl``: every finished episode, written the moment it finishes.

A long ``crowdloc eval`` that is killed keeps the episodes it finished, and ``crowdloc eval
--resume`` (the same options, the same ``--out``) runs only the others, then writes the same
tables, plots and trajectories as an uninterrupted run: the journal holds each episode whole
(its arrays, bit for bit), and the episodes are put back in grid order whatever order they
finished in, so the numbers depend neither on the interruption nor on the worker count.

The file is JSON lines: first a header with the run's spec (:func:`spec_record`), then one line
per episode, its cell and metrics in plain JSON (for a reader; NaN as null) and the episode
itself (``data``: a base64 pickle, what :func:`EpisodeJournal.resume` reads back). Each line is
flushed and synced when written; a line cut short by a kill is dropped on resume. Only open a
journal that you (or your own run) wrote: it holds pickles.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agents.common.util import jsonable
from agents.evaluate.episode import Episode
from agents.evaluate.spec import Cell, EvalSpec
from localizers.schema import ConfigError

#: the journal's file name in the output folder
JOURNAL_NAME = "episodes.jsonl"
_KIND = "crowdloc eval journal"
_FORMAT = 1


def spec_record(spec: EvalSpec) -> dict[str, Any]:
    """The spec as plain JSON values: what a resumed run must match."""
    record: dict[str, Any] = jsonable(dataclasses.asdict(spec))
    return record


def _differences(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    return [f"{key}: {old.get(key)!r} then, {new.get(key)!r} now" for key in sorted(set(old) | set(new))
            if old.get(key) != new.get(key)]  # fmt: skip


class EpisodeJournal:
    """Appends finished episodes to ``path``; :attr:`done` holds those of an earlier, interrupted run."""

    def __init__(self, path: Path, done: Mapping[Cell, Episode]) -> None:
        self.path = path
        self.done: dict[Cell, Episode] = dict(done)

    @classmethod
    def start(cls, path: Path, spec: EvalSpec) -> EpisodeJournal:
        """A new journal: ``path`` is (re)written with the header of ``spec``."""
        header = {"journal": _KIND, "format": _FORMAT, "spec": spec_record(spec)}
        with open(path, "w") as f:
            f.write(json.dumps(header) + "\n")
            f.flush()
            os.fsync(f.fileno())
        return cls(path, {})

    @classmethod
    def resume(cls, path: Path, spec: EvalSpec) -> EpisodeJournal:
        """The journal at ``path`` of an interrupted run of the same ``spec``, with its finished episodes.

        A last line cut short (the run was killed while writing it) is dropped from the file.

        Raises:
            ConfigError: no journal at ``path``, not a journal, another spec, or a damaged line
                before the last.
        """
        if not path.is_file():
            raise ConfigError(f"--resume: no {path.name} in {path.parent} (nothing to resume; run without --resume)")
        raw = path.read_bytes()
        lines = raw.split(b"\n")
        try:
            header = json.loads(lines[0])
            ok = isinstance(header, dict) and header.get("journal") == _KIND and header.get("format") == _FORMAT
        except ValueError:
            ok = False
        if not ok:
            raise ConfigError(f"--resume: {path} is not a crowdloc eval journal (format {_FORMAT})")
        differ = _differences(header["spec"], spec_record(spec))
        if differ:
            raise ConfigError(f"--resume: {path} is a run of another evaluation ({'; '.join(differ)}); "
                              "give the same options, or another --out")  # fmt: skip
        done: dict[Cell, Episode] = {}
        last = max(i for i, line in enumerate(lines) if line.strip())
        kept = len(raw)
        for i in range(1, last + 1):
            try:
                episode = pickle.loads(base64.b64decode(json.loads(lines[i])["data"], validate=True))
            except (ValueError, KeyError, TypeError, pickle.UnpicklingError, EOFError):
                if i < last:  # damage, not a kill: the run wrote on after this line
                    raise ConfigError(f"--resume: line {i + 1} of {path} is damaged; remove it (or the file)") from None
                kept = sum(len(line) + 1 for line in lines[:i])  # the run was killed while writing this line
                break
            if not isinstance(episode, Episode):
                raise ConfigError(f"--resume: line {i + 1} of {path} holds no episode")
            done.setdefault(episode.cell, episode)
        # drop a torn line and end the file with a newline, so that the next episode has a line of its own
        with open(path, "r+b") as f:
            f.truncate(kept)
            if kept and not raw[:kept].endswith(b"\n"):
                f.seek(kept)
                f.write(b"\n")
        return cls(path, done)

    def append(self, episode: Episode) -> None:
        """Write ``episode``'s line and sync it to disk."""
        row = {
            **dataclasses.asdict(episode.cell),
            "metrics": jsonable(dict(episode.metrics)),
            "data": base64.b64encode(pickle.dumps(episode, protocol=pickle.HIGHEST_PROTOCOL)).decode("ascii"),
        }
        with open(self.path, "a") as f:
            f.write(json.dumps(row) + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done.setdefault(episode.cell, episode)
