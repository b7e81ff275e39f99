"""Shared machinery of every part of ``agents``, like stable-baselines3's ``common/``.

- :mod:`agents.common.util`: argparse types, nested/flat dicts, output folders, text tables,
  the run record;
- :mod:`agents.common.sweep`: the task runner (a process pool, or Ray with ``--ray``) that
  training, evaluation, tuning and the reproductions all fan out with;
- :mod:`agents.common.plots`: matplotlib helpers and figure kinds shared by ``crowdloc eval``,
  ``crowdloc tune`` and the reproductions' reports.

May import: ``envs``, ``localizers`` and third-party packages; never another part of ``agents``.
"""
