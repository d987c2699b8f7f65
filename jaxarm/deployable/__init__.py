"""From a jaxarm env to the deployment loop: each deployable task's numpy controller (`jaxarm.deploy`) built from an
env and its params.

This package sits above both `jaxarm.envs` and `jaxarm.deploy` and imports JAX through the envs; `jaxarm.deploy`
imports neither, so a robot's computer runs it without JAX. `panda_sort.py` and `peg_insert.py` are the tasks' glue,
`registry.py` says which envs the loop runs.
"""

from jaxarm.deployable.registry import controller, runs

__all__ = ["controller", "runs"]
