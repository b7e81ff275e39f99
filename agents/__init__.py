"""crowdloc's agents, in subpackages by role (each ``__init__`` says what it may import):

- :mod:`agents.common`: shared machinery (argument types, output folders, the process-pool /
  Ray task runner, matplotlib helpers); imports no other part of ``agents``.
- :mod:`agents.policies`: the fixed policies and the driving code they share.
- :mod:`agents.experiments`: recorded experiments: scripted drivers, recording and replay,
  maps of scenes.
- :mod:`agents.rl`: reinforcement learning: the task ids' wrappers, rewards, PPO training.
- :mod:`agents.evaluate`: measuring: metrics, covariance consistency, ``crowdloc eval``.
- :mod:`agents.tune`, :mod:`agents.papers`: ``crowdloc tune`` and the papers' reproductions.
- :mod:`agents.cli` and :mod:`agents.demo` sit on top and may import all of them.

Importing ``agents`` registers what this package gives the layers below it: the task ids
``crowdloc/Active*-v0`` with Gymnasium (:mod:`agents.rl.task_ids`) and ``far_landmark_pf``'s
preparation hook, which drives a world to make its default scene map
(:func:`agents.experiments.scene_maps.prepare_far_landmark_pf`).

The flat module names ``agents.train``, ``agents.metrics``, ... import as aliases of their homes
(:data:`MOVED`), with a ``DeprecationWarning`` naming the home; the aliases go in the next release.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Sequence
from types import ModuleType

#: old module -> its new home (the old name imports the very same module object, with a warning)
MOVED: dict[str, str] = {
    "agents.util": "agents.common.util",
    "agents.sweep": "agents.common.sweep",
    "agents.plots": "agents.common.plots",
    "agents.policy_base": "agents.policies.base",
    "agents.navigation": "agents.policies.navigation",
    "agents.route_following": "agents.policies.route_following",
    "agents.replay": "agents.experiments.replay",
    "agents.scenarios": "agents.experiments.scenarios",
    "agents.scene_maps": "agents.experiments.scene_maps",
    "agents.train": "agents.rl.train",
    "agents.tasks": "agents.rl.tasks",
    "agents.rewards": "agents.rl.rewards",
    "agents.metrics": "agents.evaluate.metrics",
    "agents.consistency": "agents.evaluate.consistency",
}


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports a moved module's old name as its new module, warning once per process."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        new = MOVED[spec.name]
        # stacklevel 2: the warning names the importing line (the import machinery's frames are skipped)
        warnings.warn(
            f"{spec.name} moved to {new}; import {new} instead (the old name goes in the next release)",
            DeprecationWarning,
            stacklevel=2,
        )
        return importlib.import_module(new)  # keeps its own __name__ and __spec__: pickles name the new path

    def exec_module(self, module: ModuleType) -> None:
        del module  # already executed under its new name


if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
    sys.meta_path.append(_MovedModuleFinder())


def _register_pieces() -> None:
    from agents.rl.task_ids import register_task_ids
    from localizers.registry import set_prepare

    register_task_ids()
    set_prepare("far_landmark_pf", "agents.experiments.scene_maps:prepare_far_landmark_pf")


_register_pieces()
