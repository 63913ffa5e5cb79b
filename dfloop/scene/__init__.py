"""Scene files: a loop study described in TOML, validated strictly, run with only the stages it asks for.

A scene names a plant, a nonlinear element (with, for dynamic backlash, the physical effects it needs), the
windows to search, and the optional stages: closed-loop verification, a parameter sweep, plots. Every key is
checked (:mod:`dfloop.scene.schema`, pydantic): an unknown section or key, a wrong type (``verify = "false"``)
or an unknown element parameter raises :class:`SceneError` naming the file, the key, the closest valid name and
the expected type. ``dfloop scene-keys`` prints every key; ``docs/scenes.md`` is generated from the same schema
(``python -m dfloop.scene --reference``)::

    [plant]                      # loop transfer function seen by the element: controller * plant
    type = "tf"                  # "tf" (num, den), "zpk" (zeros, poles, gain), "ss" (A, B, C, D)
    num = [5.0]
    den = [1.0, 1.0, 0.0]
    delay = 0.0                  # optional pure delay in seconds (the plant becomes delayed(G, delay))

    [element]
    type = "Backlash"            # any DescribingFunction class exported by dfloop
    h = 1.0

    [analysis]
    omega = [0.1, 10.0]          # optional windows; chosen automatically when absent
    verify = true                # closed-loop time simulation of each predicted cycle
    plots = ["nyquist"]

    [sweep]                      # optional: follow every cycle while one number changes
    parameter = "element.h"
    values = { start = 0.5, stop = 2.0, num = 31 }
"""
from .elements import build
from .errors import Problem, SceneError
from .load import Scene, SceneLoop, find_scene, load_scene, shipped_scenes
from .reference import scene_reference
from .run import SceneReport, run_scene

__all__ = ["Scene", "SceneError", "Problem", "SceneLoop", "SceneReport", "load_scene", "run_scene", "build",
           "find_scene", "shipped_scenes", "scene_reference"]
