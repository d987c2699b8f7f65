"""A controller as files, for a robot's computer without JAX: `save(directory, controller)` writes deploy.json (the
task's numbers and the robot's name) and robot.mjb (the scene the arm is posed in); `load(directory)` builds the
controller again. Imports numpy and mujoco alone."""

import dataclasses
import json
import pathlib
import typing

import mujoco
import numpy as np

from jaxarm.deploy import peg, sort
from jaxarm.deploy.kinematics import ArmKinematics
from jaxarm.deploy.loop import Controller
from jaxarm.export.numpy_policy import EXPORT_AGAIN
from jaxarm.robots import PANDA, robot

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
    """Writes `controller`'s task and kinematic model into `directory`; returns the files written. ValueError for a
    controller of none of `CONTROLLERS`' classes."""
    names = [name for name, (kind, _) in CONTROLLERS.items() if isinstance(controller, kind)]
    if not names:
        kinds = ", ".join(kind.__name__ for kind, _ in CONTROLLERS.values())
        raise ValueError(f"no deploy files for a {type(controller).__name__}; they are written for {kinds}")
    (name,) = names
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    task_path, model_path = directory / TASK_FILE, directory / MODEL_FILE
    task = controller.task
    record = {"task": name, "robot": controller.kinematics.robot.name, "numbers": _plain(task)}
    task_path.write_text(json.dumps(record, indent=1))
    mujoco.mj_saveModel(controller.kinematics.model, str(model_path))
    return [task_path, model_path]


def load(directory: str | pathlib.Path) -> Controller:
    """The controller `save` wrote into `directory`; ValueError naming the file and what is wrong where deploy.json
    or robot.mjb is damaged, edited or from another version; OSError where one cannot be read."""
    directory = pathlib.Path(directory)
    task_path, model_path = directory / TASK_FILE, directory / MODEL_FILE
    try:
        data = json.loads(task_path.read_text())
        controller_class, task_class = CONTROLLERS[data["task"]]
        task = _record(task_class, data["numbers"])
        # Files written before deploy.json named its robot are the Panda's, the only robot there was.
        description = robot(data.get("robot", PANDA.name))
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError, AttributeError) as error:
        # KeyError: a task or field it lacks; TypeError, AttributeError: parts of the wrong JSON type.
        raise ValueError(
            f"{task_path} is damaged or from another version ({type(error).__name__}: {error}); {EXPORT_AGAIN}"
        ) from None
    if not model_path.is_file():
        raise ValueError(f"no {model_path}; {EXPORT_AGAIN}")
    try:
        kinematics = ArmKinematics(mujoco.MjModel.from_binary_path(str(model_path)), description)
    except (ValueError, KeyError) as error:  # KeyError: a model without the robot's joint, body or site names
        raise ValueError(
            f"{model_path} is not a {description.name} scene ({type(error).__name__}: {error}); {EXPORT_AGAIN}"
        ) from None
    return controller_class(task, kinematics)
