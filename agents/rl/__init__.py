"""Reinforcement learning: the task ids, their reward and PPO training (``crowdloc train``).

- :mod:`agents.rl.tasks`: the ``crowdloc/*Task-v0`` ids' entry point (a world, its
  localizer and the reward, from a training config);
- :mod:`agents.rl.rewards`: the active-localization reward wrapper;
- :mod:`agents.rl.observation`: what a task's policy observes, and the task's route;
- :mod:`agents.rl.residual`: a policy's action as a correction of a fixed policy's command;
- :mod:`agents.rl.config`: a training run's config (the YAML file and its ``--set`` / ``--replace``
  changes), ``EVAL_SEED_BASE``;
- :mod:`agents.rl.train`: PPO runs on a config, with checkpoints and exact resume.

May import: ``envs``, ``localizers``, :mod:`agents.common`, :mod:`agents.policies` (the fixed
policy a residual action corrects); never :mod:`agents.experiments`, :mod:`agents.evaluate`,
:mod:`agents.tune`, :mod:`agents.papers`.
"""
