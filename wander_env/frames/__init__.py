"""Where the camera's frames come from: the posed scene and the frame sources that read
one PTU trajectory per step.

- :mod:`~wander_env.frames.stage`: :class:`~wander_env.frames.stage.Stage`, the model and
  data posed at a time and camera angles, and the camera's renderer;
- :mod:`~wander_env.frames.source`: what a frame source is
  (:class:`~wander_env.frames.source.FrameSource`, :class:`~wander_env.frames.source.FrameParams`);
- one module per source: :mod:`~wander_env.frames.exact` (every frame rendered),
  :mod:`~wander_env.frames.keyframes` (keys, the frames between them synthesised),
  :mod:`~wander_env.frames.panorama` (a cube map of the static world, a keyframe source
  for the moving objects);
- their maths: :mod:`~wander_env.frames.keyframe_maths` (in-between frames from two keys
  and the scene's geometry), :mod:`~wander_env.frames.cube` (the cube map) and
  :mod:`~wander_env.frames.raycast` (masks and key geometry by ray casting where the
  moving objects are primitives);
- :mod:`~wander_env.frames.registry`: the modes by name (``WanderConfig.frames``), with
  nothing heavy imported: a new mode is one more source module and one registry entry.

This package's ``__init__`` imports nothing (importing the registry stays light).
"""
