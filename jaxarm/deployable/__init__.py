"""From a jaxarm env to the deployment loop: each deployable task's numpy controller (`jaxarm.deploy`) built from an
env and its params.

This package sits above both `jaxarm.envs` and `jaxarm.deploy` and imports JAX through the envs; `jaxarm.deploy`
imports neither, so a robot's computer runs it without JAX. `panda_sort.py` and `peg_insert.py` are the tasks' glue,
`registry.py` lists them (`DEPLOYABLES`), one entry each (`base.Deployable`: controller, scene, episode).
"""

from jaxarm.deployable.registry import DEPLOYABLES, camera_controller, camera_renderer, controller, entry, runs

__all__ = ["DEPLOYABLES", "camera_controller", "camera_renderer", "controller", "entry", "runs"]
