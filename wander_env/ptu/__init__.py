"""The pan-tilt unit (PTU): a FLIR PTU-E46/D46-like two-axis stepper positioner.

Public angles are in degrees; inside, each axis works in PTU *positions* (motor
steps, ``resolution_arcsec`` arc-seconds each: 92.5714″ = 0.025714° on the paper's
unit), as the FLIR firmware's ASCII protocol does (``PP``/``TP`` targets, ``PS``
speed, ``PA`` acceleration, ``PB`` base speed, ``PU`` upper speed, ``PN``/``PX``
limits).

One module per part of the model:

- :mod:`wander_env.ptu.units`: degrees ↔ positions, and the position a unit reports;
- :mod:`wander_env.ptu.params`: :class:`~wander_env.ptu.params.PTUParams`, the unit's
  limits, speeds and mechanics, and its presets;
- :mod:`wander_env.ptu.axis`: one axis's motion, pure maths (trapezoid moves, exact
  stepping);
- :mod:`wander_env.ptu.mechanics`: backlash and the camera's offset from the tilt hinge;
- :mod:`wander_env.ptu.link`: the 9600-baud serial link's command latency;
- :mod:`wander_env.ptu.unit`: :class:`~wander_env.ptu.unit.PanTiltUnit`, the stateful
  unit the env steps, and the :class:`~wander_env.ptu.unit.Trajectory` of one step.

Conventions: positive pan turns the camera left (counter-clockwise seen from above;
FLIR: ``PO828`` pans 21.3° left); positive tilt raises it. The PTU frame has its
origin on the tilt hinge, x forward (optical axis at pan = tilt = 0), y left, z up.
"""
