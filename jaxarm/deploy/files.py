"""A controller as files, for a robot's computer without JAX: `save(directory, controller)` writes deploy.json (the
task's numbers) and robot.mjb (the scene the arm is posed in); `load(directory)` builds the controller again.
Imports numpy and mujoco alone."""

import dataclasses
import json
import pathlib
import typing

import mujoco
import numpy as np

from jaxarm.deploy import peg, sort
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import Controller

TASK_FILE = "deploy.json"
MODEL_FILE = "robot.mjb"
CONTROLLERS = {"sort": (sort.SortController, sort.SortTask), "peg": (peg.PegController, peg.PegTask)}
"""Each task's controller class and the record of its numbers, by the name deploy.json gives."""


def _plain(value):
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {field.name: _plain(getattr(value, field.name)) for field in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _record(kind: type, data: dict):
    """The dataclass `kind` from `_plain`'s dict: arrays and nested records as their fields' types say."""
    hints = typing.get_type_hints(kind)
    values = {}
    for name, value in data.items():
        hint = hints[name]
        if hint is np.ndarray:
            value = np.array(value, np.float64)
        elif isinstance(hint, type) and dataclasses.is_dataclass(hint):
            value = _record(hint, value)
        values[name] = value
    return kind(**values)


def save(directory: str | pathlib.Path, controller: Controller) -> list[pathlib.Path]:
    """Writes `controller`'s task and kinematic model into `directory`; returns the files written."""
    name = next(name for name, (kind, _) in CONTROLLERS.items() if isinstance(controller, kind))
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    task_path, model_path = directory / TASK_FILE, directory / MODEL_FILE
    task = controller.task  # type: ignore[attr-defined]
    task_path.write_text(json.dumps({"task": name, "numbers": _plain(task)}, indent=1))
    mujoco.mj_saveModel(controller.kinematics.model, str(model_path))  # type: ignore[attr-defined]
    return [task_path, model_path]


def load(directory: str | pathlib.Path) -> Controller:
    """The controller `save` wrote into `directory`."""
    directory = pathlib.Path(directory)
    data = json.loads((directory / TASK_FILE).read_text())
    controller_class, task_class = CONTROLLERS[data["task"]]
    model = mujoco.MjModel.from_binary_path(str(directory / MODEL_FILE))
    return controller_class(_record(task_class, data["numbers"]), ArmKinematics(model))
