"""`jaxarm.deploy` is a floor of its own: none of its modules imports JAX or `jaxarm.envs`, so a robot's computer
runs the deployment loop with numpy and MuJoCo's C library alone. The glue from an env to the loop lives above both,
in `jaxarm.deployable`.

Read from the source as tests/envs/test_imports.py reads it (imports inside functions count), and checked again by
importing every module of the package in a fresh interpreter.
"""

import ast
import subprocess
import sys

from tests.envs.test_imports import jaxarm_import_graph, module_names

DEPLOY = "jaxarm.deploy"
ENVS = "jaxarm.envs"
JAX_PACKAGES = ("jax", "jaxlib", "flax", "optax", "orbax", "brax", "chex", "mujoco.mjx")
"""What brings JAX into a process (MJX is JAX)."""


def within(name: str, package: str) -> bool:
    return name == package or name.startswith(f"{package}.")


def deploy_modules() -> list[str]:
    return sorted(name for name in module_names() if within(name, DEPLOY))


def absolute_imports(path) -> set[str]:
    """Every module name a source file imports absolutely, anywhere in it."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found.add(node.module)
    return found


def reachable(graph: dict[str, set[str]], start: list[str]) -> set[str]:
    """The jaxarm modules that importing `start` runs: those they import, in turn, and each one's packages."""
    seen: set[str] = set()
    todo = list(start)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        parts = name.split(".")
        todo += [".".join(parts[:end]) for end in range(1, len(parts))]
        todo += graph[name]
    return seen


def test_no_module_of_deploy_imports_jax_or_the_envs():
    paths = module_names()
    for name in deploy_modules():
        banned = {
            imported
            for imported in absolute_imports(paths[name])
            if any(within(imported, package) for package in (*JAX_PACKAGES, ENVS))
        }
        assert not banned, f"{name} imports {sorted(banned)}"
    envs = {name for name in reachable(jaxarm_import_graph(), deploy_modules()) if within(name, ENVS)}
    assert not envs, f"importing {DEPLOY} imports {sorted(envs)}"


def test_the_check_sees_an_env_imported_through_another_module():
    graph = {"jaxarm.deploy.a": {"jaxarm.util"}, "jaxarm.util": {"jaxarm.envs.base"}, "jaxarm.envs.base": set()}
    graph |= {"jaxarm": set(), "jaxarm.deploy": set(), "jaxarm.envs": set()}
    assert "jaxarm.envs.base" in reachable(graph, ["jaxarm.deploy.a"])


def test_importing_every_module_of_deploy_loads_no_jax():
    script = (
        "import importlib, sys\n"
        f"for name in {deploy_modules()!r}:\n"
        "    importlib.import_module(name)\n"
        "print(' '.join(sorted(sys.modules)))\n"
    )
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    banned = [name for name in loaded if any(within(name, package) for package in (*JAX_PACKAGES, ENVS))]
    assert not banned, f"importing {DEPLOY} loads {banned}"
