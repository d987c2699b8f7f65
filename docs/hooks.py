"""MkDocs hooks (mkdocs.yml `hooks:`): pages that show what the repository already says, so that nothing is kept twice.

- results.md includes BENCHMARKS.md from the repository's root, its links to docs/ made relative to the site;
  benchmarks-log.md's links to BENCHMARKS.md point at that page.
- `<!-- presets -->` and `<!-- envs -->` become tables of the named presets (`@preset` in experiments/configs/)
  and registered envs (`register(...)` in jaxarm/envs/registry.py), read from the source without importing it:
  the docs build imports no JAX.
"""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
BENCHMARKS = "<!-- BENCHMARKS.md -->"
PRESETS = "<!-- presets -->"
ENVS = "<!-- envs -->"


def _string_args(call: ast.Call) -> list[str]:
    return [arg.value for arg in call.args if isinstance(arg, ast.Constant) and isinstance(arg.value, str)]


def preset_rows() -> list[tuple[str, str]]:
    """(name, description) of every function decorated with `@preset("...")` in experiments/configs/, by name."""
    rows = []
    for path in sorted((ROOT / "experiments" / "configs").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.FunctionDef):
                continue
            for decorator in node.decorator_list:
                if isinstance(decorator, ast.Call) and getattr(decorator.func, "id", None) == "preset":
                    rows.append((node.name, _string_args(decorator)[0]))
    return sorted(rows)


def env_rows() -> list[tuple[str, str]]:
    """(name, description) of every `register(name, target, description, ...)` in jaxarm/envs/registry.py."""
    tree = ast.parse((ROOT / "jaxarm" / "envs" / "registry.py").read_text())
    rows = []
    for node in tree.body:
        call = node.value if isinstance(node, ast.Expr) else None
        if isinstance(call, ast.Call) and getattr(call.func, "id", None) == "register":
            name, _, description = _string_args(call)[:3]
            rows.append((name, description))
    return sorted(rows)


def table(header: tuple[str, str], rows: list[tuple[str, str]]) -> str:
    lines = [f"| {header[0]} | {header[1]} |", "|---|---|"]
    escaped = [(name, description.replace("|", r"\|")) for name, description in rows]
    lines += [f"| `{name}` | {description} |" for name, description in escaped]
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:
    if BENCHMARKS in markdown:
        text = (ROOT / "BENCHMARKS.md").read_text()
        body = text.split("\n", 1)[1]  # without its "# Benchmarks" title: the page has its own
        markdown = markdown.replace(BENCHMARKS, body.replace("](docs/", "]("))
    if page.file.src_uri == "benchmarks-log.md":
        markdown = markdown.replace("](../BENCHMARKS.md", "](results.md").replace("](docs/results/", "](results/")
    if PRESETS in markdown:
        markdown = markdown.replace(PRESETS, table(("preset", "what it trains"), preset_rows()))
    if ENVS in markdown:
        markdown = markdown.replace(ENVS, table(("env", "what it is"), env_rows()))
    return markdown
