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
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from agents.common.util import jsonable
from agents.evaluate.episode import Episode
from agents.evaluate.spec import EvalSpec
from core.schema import ConfigError

#: the journal's file name in the output folder
JOURNAL_NAME = "episodes.jsonl"
_FORMAT = 1
Item = TypeVar("Item")


def spec_record(spec: EvalSpec) -> dict[str, Any]:
    """The spec as plain JSON values: what a resumed run must match."""
    record: dict[str, Any] = jsonable(dataclasses.asdict(spec))
    return record


def _differences(old: Mapping[str, Any], new: Mapping[str, Any]) -> list[str]:
    return [f"{key}: {old.get(key)!r} then, {new.get(key)!r} now" for key in sorted(set(old) | set(new))
            if old.get(key) != new.get(key)]  # fmt: skip


class Journal(Generic[Item]):
    """Appends finished items (what one task of a run gives) to ``path``, each under its key;
    :attr:`done` holds those of an earlier, interrupted run of the same record.

    A subclass names its :attr:`KIND` and :attr:`ITEM` type and says how an item is keyed
    (:meth:`key`) and what of it a reader sees in plain JSON (:meth:`readable`).
    """

    KIND: ClassVar[str]
    ITEM: ClassVar[type]
    RUN: ClassVar[str]  # what a run is called in messages ("evaluation", "benchmark")

    def __init__(self, path: Path, done: Mapping[Hashable, Item]) -> None:
        self.path = path
        self.done: dict[Hashable, Item] = dict(done)

    @staticmethod
    def key(item: Item) -> Hashable:
        """What identifies ``item`` in the run (its task)."""
        raise NotImplementedError

    @staticmethod
    def readable(item: Item) -> dict[str, Any]:
        """The plain-JSON part of ``item``'s line, for a reader."""
        raise NotImplementedError

    @classmethod
    def _start(cls, path: Path, record: Mapping[str, Any]) -> Any:
        """A new journal: ``path`` is (re)written with the header of the run's ``record``."""
        header = {"journal": cls.KIND, "format": _FORMAT, "spec": dict(record)}
        with open(path, "w") as f:
            f.write(json.dumps(header) + "\n")
            f.flush()
            os.fsync(f.fileno())
        return cls(path, {})

    @classmethod
    def _resume(cls, path: Path, record: Mapping[str, Any]) -> Any:
        """The journal at ``path`` of an interrupted run of the same ``record``, with its finished items.

        A last line cut short (the run was killed while writing it) is dropped from the file.

        Raises:
            ConfigError: no journal at ``path``, not a journal of this kind, another run, or a
                damaged line before the last.
        """
        if not path.is_file():
            raise ConfigError(f"--resume: no {path.name} in {path.parent} (nothing to resume; run without --resume)")
        raw = path.read_bytes()
        lines = raw.split(b"\n")
        try:
            header = json.loads(lines[0])
            ok = isinstance(header, dict) and header.get("journal") == cls.KIND and header.get("format") == _FORMAT
        except ValueError:
            ok = False
        if not ok:
            raise ConfigError(f"--resume: {path} is not a {cls.KIND} (format {_FORMAT})")
        differ = _differences(header["spec"], dict(record))
        if differ:
            raise ConfigError(f"--resume: {path} is a run of another {cls.RUN} ({'; '.join(differ)}); "
                              "give the same options, or another --out")  # fmt: skip
        done: dict[Hashable, Any] = {}
        last = max(i for i, line in enumerate(lines) if line.strip())
        kept = len(raw)
        for i in range(1, last + 1):
            try:
                item: Any = pickle.loads(base64.b64decode(json.loads(lines[i])["data"], validate=True))
            except (ValueError, KeyError, TypeError, pickle.UnpicklingError, EOFError):
                if i < last:  # damage, not a kill: the run wrote on after this line
                    raise ConfigError(f"--resume: line {i + 1} of {path} is damaged; remove it (or the file)") from None
                kept = sum(len(line) + 1 for line in lines[:i])  # the run was killed while writing this line
                break
            if not isinstance(item, cls.ITEM):
                raise ConfigError(f"--resume: line {i + 1} of {path} holds no {cls.ITEM.__name__}")
            done.setdefault(cls.key(item), item)  # type: ignore[arg-type]  # checked just above: an ITEM
        # drop a torn line and end the file with a newline, so that the next item has a line of its own
        with open(path, "r+b") as f:
            f.truncate(kept)
            if kept and not raw[:kept].endswith(b"\n"):
                f.seek(kept)
                f.write(b"\n")
        return cls(path, done)

    def append(self, item: Item) -> None:
        """Write ``item``'s line and sync it to disk."""
        row = {**self.readable(item),
               "data": base64.b64encode(pickle.dumps(item, protocol=pickle.HIGHEST_PROTOCOL)).decode("ascii")}  # fmt: skip
        with open(self.path, "a") as f:
            f.write(json.dumps(row) + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done.setdefault(self.key(item), item)


class EpisodeJournal(Journal[Episode]):
    """``crowdloc eval``'s journal: its episodes, keyed by their cell."""

    KIND = "crowdloc eval journal"
    ITEM = Episode
    RUN = "evaluation"

    @staticmethod
    def key(item: Episode) -> Hashable:
        return item.cell

    @staticmethod
    def readable(item: Episode) -> dict[str, Any]:
        return {**dataclasses.asdict(item.cell), "metrics": jsonable(dict(item.metrics))}

    @classmethod
    def start(cls, path: Path, spec: EvalSpec) -> EpisodeJournal:
        """A new journal: ``path`` is (re)written with the header of ``spec``."""
        journal: EpisodeJournal = cls._start(path, spec_record(spec))
        return journal

    @classmethod
    def resume(cls, path: Path, spec: EvalSpec) -> EpisodeJournal:
        """The journal at ``path`` of an interrupted run of the same ``spec`` (:meth:`Journal._resume`)."""
        journal: EpisodeJournal = cls._resume(path, spec_record(spec))
        return journal
