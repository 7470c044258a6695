"""The scanpath experiment's recorder: what the agent looked at, named as in the scene file.

:class:`ScanpathRecorder` watches a run of the attention agent
(:class:`experiments.runs.episode.Recorder`): per decision the saliency map, the gaze,
the scene object under the fovea (the fixation's area of interest) and, for the salient
point ``P``, the object under it and the one most of the detection box around it sees;
each found by casting the pixel's ray into the scene in the env's pose when the agent
decided (:func:`wander_env.camera.cast_pixel`). :func:`object_names` maps the model's
geom names to the scene file's names. :mod:`experiments.paper.scanpath` runs it.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from agents.attention import AgentParams, AttentionAgent
from experiments.analysis.metrics import hit_box
from experiments.runs.episode import Recorder
from wander_env.camera import cast_pixel
from wander_env.entities import object_body_name
from wander_env.scene_config import SceneConfig

__all__ = ["ScanpathRecorder", "object_names"]


def object_names(scene: SceneConfig) -> dict[str, str]:
    """The scene's objects by their geom's name in the model -> their name in the scene
    file (a moving object's geom is ``object_k``; an object the file leaves unnamed keeps
    its geom's name).

    >>> from wander_env.scenes import load_scene_config
    >>> names = object_names(load_scene_config("office"))
    >>> names["object_1"], names["object_2"], names["mug"]
    ('cube', 'beach_ball', 'mug')
    """
    names: dict[str, str] = {}
    for i, o in enumerate(scene.static_objects):
        geom = o.name or f"static_{i}"
        names[geom] = geom
    for k, o in enumerate(scene.moving_objects, 1):
        names[object_body_name(k)] = o.name or object_body_name(k)
    return names


class ScanpathRecorder(Recorder):
    """Watches the agent of a run (:mod:`experiments.runs.recorders`): per decision the
    saliency map, the gaze and which scene object the box around ``P`` sees (ray casts
    in ``env``'s pose when the agent decided; objects named as in the scene file,
    :func:`object_names`)."""

    def __init__(self, env: Any, box: int = 8) -> None:
        self._env, self._box = env.unwrapped, box
        self._objects = object_names(self._env.scene)
        self.maps: list[np.ndarray] = []
        self.map_gazes: list[tuple[float, float]] = []
        # Per decision with a P: (object under P, object most of the box sees); "" = none.
        self.labels: list[tuple[str, str]] = []
        # Per decision: the object under the fovea (the fixation's area of interest).
        self.fovea_labels: list[str] = []

    def on_reset(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        self.maps, self.map_gazes, self.labels, self.fovea_labels = [], [], [], []

    def on_act(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        if agent.decided:
            gaze = tuple(float(g) for g in np.asarray(obs["gaze"]).reshape(2))
            self.maps.append(np.asarray(agent.saliency, np.float32).copy())
            self.map_gazes.append(gaze)
            p = agent.params
            self.fovea_labels.append(self._object(p, (p.width_px // 2, p.height_px // 2)))
            if agent.target is not None:
                self.labels.append(self._objects_at(p, agent.target))

    def _object(self, p: AgentParams, xy: tuple[int, int]) -> str:
        geom = cast_pixel(self._env.model, self._env.data, xy, p.width_px, p.height_px)[2]
        return self._objects.get(geom, "")

    def _objects_at(self, p: AgentParams, xy: tuple[int, int]) -> tuple[str, str]:
        """(the object under ``xy``, the object most of the box's pixels see)."""
        x0, x1, y0, y1 = hit_box(xy, (p.height_px, p.width_px), self._box)
        seen: Counter[str] = Counter()
        for y in range(y0, y1):
            for x in range(x0, x1):
                seen[self._object(p, (x, y))] += 1
        seen.pop("", None)
        return self._object(p, xy), seen.most_common(1)[0][0] if seen else ""
