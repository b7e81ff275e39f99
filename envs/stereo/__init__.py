"""The machinery of the stereo camera sensor (:mod:`envs.sensors.stereo_camera`).

- :mod:`.scene`: the world as a forward camera sees it, packed into flat arrays (static solids
  with their façades, the walls, the moving bodies' parts with their colours);
- :mod:`.render`: the image mode's column ray caster (RGB images with exposure and noise);
- :mod:`.geometric`: the fast mode, the same edges computed from the geometry;
- :mod:`.sight`: the fast mode's lines of sight (what an image column meets, hides and shows behind).

The image functions that also run on real camera frames (the vertical edge filter, trinocular
matching, the paper's triangulation) are in :mod:`envs.stereo.vision`.
"""
