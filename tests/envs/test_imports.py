"""No import cycles between jaxarm's modules, and no runner module importing a learner, read from the source
(ast), imports inside functions included.

A module imported only inside a function (the usual way to hide a cycle) still counts. A package's
`__init__` importing its own modules is not a cycle unless a module imports the package back explicitly.
"""

import ast
from pathlib import Path

import jaxarm

ROOT = Path(jaxarm.__file__).parent


def module_names() -> dict[str, Path]:
    """Every module and package of jaxarm, by dotted name."""
    names = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def imported_modules(name: str, path: Path, modules: set[str]) -> set[str]:
    """The jaxarm modules that module `name` (at `path`) imports anywhere in its source."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            # `from package import module` imports the module (its package only as every import does, which
            # is not counted); `from module import name` takes the name from `module`.
            submodules = {f"{base}.{alias.name}" for alias in node.names} & modules
            found.update(submodules)
            if len(submodules) < len(node.names):
                found.add(base)
    return {imported for imported in found if imported in modules and imported != name}


def import_cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph[node]):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return cycles


def jaxarm_import_graph() -> dict[str, set[str]]:
    modules = module_names()
    return {name: imported_modules(name, path, set(modules)) for name, path in modules.items()}


def test_the_cycle_finder_finds_a_cycle_through_three_modules():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [{"a", "b", "c"}]


def test_imports_inside_functions_count(tmp_path):
    path = tmp_path / "env.py"
    path.write_text("def render():\n    from jaxarm.envs.arm2d import render\n")
    modules = {"jaxarm.envs.arm2d", "jaxarm.envs.arm2d.render"}
    assert imported_modules("jaxarm.envs.arm2d.env", path, modules) == {"jaxarm.envs.arm2d.render"}


def test_the_graph_sees_imports_of_modules_from_packages():
    graph = jaxarm_import_graph()
    assert "jaxarm.envs.panda.render" in graph["jaxarm.envs.panda.base"]
    assert "jaxarm.agents.ppo.losses" in graph["jaxarm.agents.ppo.train"], "`from jaxarm.agents.ppo import losses`"
    assert "jaxarm.agents.ppo" not in graph["jaxarm.agents.ppo.train"], "only the module, not its package"


def test_no_module_of_jaxarm_imports_itself_through_others():
    assert import_cycles(jaxarm_import_graph()) == []


LEARNER_PACKAGES = ("jaxarm.agents.ppo", "jaxarm.agents.td3")
"""The learners' own modules, which the runner reaches only through the learner registry (jaxarm.agents.registry)."""


def learner_imports(graph: dict[str, set[str]], importers: str = "jaxarm.runner") -> set[tuple[str, str]]:
    """(module, learner module) for each module in the package `importers` that imports a learner's module."""
    return {
        (name, imported)
        for name, imports in graph.items()
        if name == importers or name.startswith(f"{importers}.")
        for imported in imports
        if any(imported == package or imported.startswith(f"{package}.") for package in LEARNER_PACKAGES)
    }


def test_the_learner_import_rule_finds_a_runner_module_importing_a_learner():
    graph = {
        "jaxarm.runner.loop": {"jaxarm.agents.ppo.distill", "jaxarm.agents.registry"},
        "jaxarm.agents.registry": {"jaxarm.agents.ppo"},
    }
    assert learner_imports(graph) == {("jaxarm.runner.loop", "jaxarm.agents.ppo.distill")}


def test_the_runner_imports_no_learner_module():
    # A capability of one learner (a warm start, being taught) is an entry in the registry, not an import here.
    assert learner_imports(jaxarm_import_graph()) == set()
