"""crowdloc's foundation, below both the worlds (:mod:`envs`) and the methods (:mod:`localizers`):
what they share, importing nothing else of crowdloc.

- :mod:`core.schema`: strict loading of frozen-dataclass configs from YAML and keyword
  overrides, and :class:`core.schema.ConfigError`, the one error a bad setting raises;
- :mod:`core.geometry`: angles, poses and their composition, fields of view;
- :mod:`core.raycast`: rays and lines of sight against segments and discs (numba);
- :mod:`core.motion`: the odometry motion model, its noise and its sampling;
- :mod:`core.types`: the known map, the measurement dataclasses, a pose estimate and an overlay.
"""
