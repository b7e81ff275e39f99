"""A command's output folder and the manifest of what the command wrote there.

``crowdloc eval``, ``benchmark``, ``demo`` and ``train`` each write a folder of results. Each keeps
a manifest in it, :data:`MANIFEST_NAME`: the command's name and the files it wrote, relative to
the folder. The manifest is what makes ``--overwrite`` safe: it deletes the files the manifest
lists and nothing else, and it refuses

- a folder that holds another command's manifest (an eval folder given to ``crowdloc benchmark``,
  say: each command's files, and its resume journal, stay its own);
- a file at a fixed path the command writes (``report.md``; a pattern such as ``plots/*.png``
  names no file in particular) that the manifest does not list: a file of the user's, or of a
  run killed before it could record what it wrote. Nothing is deleted then; the message names
  the files.

What a command wrote is recorded as it goes (:meth:`OutputFolder.record`, for a journal the
moment it exists) and when it ends, however it ends short of being killed
(:meth:`OutputFolder.record_written`: the files under its output patterns that are new or
changed since the command started). Files the user puts in the folder stay untouched.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from agents.common.util import make_out_dir
from core.schema import ConfigError
from localizers.range_table import write_atomically

#: the manifest's file name in every output folder
MANIFEST_NAME = "crowdloc-manifest.json"
#: the most files a message lists before "and N more"
_SHOWN = 5


def _shown(names: Sequence[str]) -> str:
    return ", ".join(names[:_SHOWN]) + (f" and {len(names) - _SHOWN} more" if len(names) > _SHOWN else "")


def _stat_key(path: Path) -> tuple[int, int, int]:
    st = path.stat()
    return st.st_ino, st.st_size, st.st_mtime_ns


def _files_under(folder: Path) -> Iterator[Path]:
    for root, _dirs, files in os.walk(folder):
        for name in files:
            yield Path(root, name)


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The manifest of ``folder`` (``{"command": ..., "files": [...]}``), or None where it has none.

    Raises:
        ConfigError: a manifest that is not one (unreadable JSON, or without its two fields).
    """
    path = folder / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable manifest ({exc}); move it away or give another --out") from None
    if not (isinstance(doc, dict) and isinstance(doc.get("command"), str) and isinstance(doc.get("files"), list)):
        raise ConfigError(f"{path}: not a crowdloc manifest (it needs 'command' and 'files'); move it away or give another --out")
    return doc


class OutputFolder:
    """An output folder opened by :func:`open_output_folder`: records what the command writes.

    Use it as a context manager around the command's work: on leaving (an error or Ctrl-C
    included) it records the files the command wrote (:meth:`record_written`).
    """

    def __init__(self, path: Path, command: str, patterns: Sequence[str], recorded: Iterable[str]) -> None:
        self.path = path
        self.command = command
        self.patterns = tuple(patterns)
        self._recorded = set(recorded)
        self._before = {self._rel(p): _stat_key(p) for p in _files_under(path)}
        self._save()

    def _rel(self, path: Path) -> str:
        return path.relative_to(self.path).as_posix()

    @property
    def recorded(self) -> frozenset[str]:
        """The files (relative to the folder) the manifest lists."""
        return frozenset(self._recorded)

    def _save(self) -> None:
        doc = {
            "command": self.command,
            "about": f"the files {self.command} wrote in this folder; its --overwrite deletes these and nothing else",
            "files": sorted(self._recorded),
        }
        write_atomically(self.path / MANIFEST_NAME, lambda tmp: tmp.write_text(json.dumps(doc, indent=1) + "\n"))

    def record(self, *paths: Path) -> None:
        """Add files the command has just written (paths under the folder) to the manifest now."""
        new = {self._rel(Path(p)) for p in paths} - self._recorded
        if new:
            self._recorded |= new
            self._save()

    def written(self) -> list[Path]:
        """The files under the command's output patterns that are new or changed since it started."""
        found: set[Path] = set()
        for pattern in self.patterns:
            found.update(p for p in self.path.glob(pattern) if p.is_file())
        return sorted(p for p in found if self._before.get(self._rel(p)) != _stat_key(p))

    def record_written(self) -> None:
        """Record :meth:`written` (at the end of the command, and where a long one wants to)."""
        self.record(*self.written())

    def __enter__(self) -> OutputFolder:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.record_written()


def _conflicts(out: Path, patterns: Sequence[str], recorded: Iterable[str]) -> list[str]:
    """Files at the command's fixed output paths (its patterns without a wildcard: ``report.md``,
    not ``plots/*.png``, which names no file in particular) that its manifest does not list."""
    mine = set(recorded)
    fixed = [pattern for pattern in patterns if not any(c in pattern for c in "*?[")]
    return sorted(rel for rel in fixed if (out / rel).is_file() and rel not in mine)


def _delete_recorded(out: Path, recorded: Iterable[str]) -> None:
    """Delete the recorded files, then the folders that held them once empty (deepest first)."""
    folders: set[Path] = set()
    for rel in recorded:
        path = out / rel
        if path.is_file() or path.is_symlink():
            path.unlink()
        parent = Path(rel).parent
        while parent != Path("."):
            folders.add(out / parent)
            parent = parent.parent
    for folder in sorted(folders, key=lambda f: len(f.parts), reverse=True):
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def open_output_folder(
    out: Path, patterns: Sequence[str], *, command: str, overwrite: bool, resume: bool = False, flag: str = "--out"
) -> OutputFolder:
    """Make ``out`` ready for ``command``, which writes files matching the glob ``patterns`` there,
    before any work, and return it with its manifest (module docstring).

    A folder that holds anything but an empty manifest is refused, unless ``resume`` (the command
    continues the run that is there) or ``overwrite``: the files the manifest lists are deleted,
    everything else stays.

    Raises:
        ConfigError: naming ``flag`` and ``out``: a file in the folder's place, a folder that
            cannot be created or written, another command's folder, a folder that is not empty
            (without ``overwrite`` or ``resume``), or, with ``overwrite``, files at the command's
            output paths that its manifest does not list.
    """
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{flag} {out} is a file, not a folder")
    manifest = read_manifest(out) if out.is_dir() else None
    held = sorted(p.name for p in out.iterdir() if p.name != MANIFEST_NAME) if out.is_dir() else []
    recorded: list[str] = []
    if held:
        if manifest is not None and manifest["command"] != command:
            raise ConfigError(
                f"{flag} {out} holds the results of {manifest['command']} ({MANIFEST_NAME}); {command} neither "
                "continues nor replaces another command's results: give another --out"
            )
        recorded = [str(f) for f in manifest["files"]] if manifest is not None else []
        if not resume:
            if not overwrite:
                raise ConfigError(
                    f"{flag} {out} is not empty ({_shown(held)}); give --overwrite to replace what {command} wrote there "
                    "(other files stay), or another --out"
                )
            conflicts = _conflicts(out, patterns, recorded)
            if conflicts:
                raise ConfigError(
                    f"{flag} {out}: {_shown(conflicts)} would be replaced, but {command} has no record of writing "
                    f"{'them' if len(conflicts) > 1 else 'it'} ({MANIFEST_NAME}): a file of yours, or of a run killed "
                    "before it recorded its files. Nothing was deleted: move those files away, or give another --out"
                )
            _delete_recorded(out, recorded)
            recorded = []
    return OutputFolder(make_out_dir(out, flag), command, patterns, recorded)
