"""Recorded experiments: what drives the robot, what is recorded, and how it is replayed.

- :mod:`agents.experiments.scenarios`: scripted drivers (open-loop paths, the soccer
  field's robot and referee, patrols, shoves) and the kidnap;
- :mod:`agents.experiments.replay`: record a run's observation leaves once and replay them
  into any localizer, so every method sees identical data;
- :mod:`agents.experiments.scene_maps`: maps of scenes (``crowdloc map``), the far-landmark
  filter's prepare hook and the LIDAR reference's settings.

May import: ``envs``, ``localizers``, :mod:`agents.common`, :mod:`agents.policies`; never
:mod:`agents.rl`, :mod:`agents.evaluate`, :mod:`agents.tune`, :mod:`agents.papers`.
"""
