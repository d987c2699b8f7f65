"""The README stays short and its two commands stay the ones the scripts and CI run; the docs' generated tables
read the source they describe (docs/hooks.py). The site itself is built by CI (`mkdocs build --strict`)."""

import importlib.util
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parent.parent
README_LIMIT = 8192
"""Bytes: the README says what, how to install, the two commands, one result and where next; the rest is in docs/."""


def readme_commands() -> list[str]:
    """The README's bash blocks, one string each."""
    return re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), re.DOTALL)


def test_readme_is_short():
    assert len((ROOT / "README.md").read_bytes()) <= README_LIMIT


def test_readme_commands_are_what_the_scripts_and_ci_run():
    commands = readme_commands()
    assert "bash scripts/setup.sh && .venv/bin/python -m experiments.run --config ppo_arm2d\n" in commands
    assert "bash scripts/test.sh\n" in commands
    ci = (ROOT / ".ci" / "run").read_text()
    suite = [line for line in ci.splitlines() if line.endswith(" bash scripts/test.sh || status=1")]
    assert len(suite) == 1 and suite[0].startswith("JAXARM_PYTHON=")
    assert "def ppo_arm2d()" in (ROOT / "experiments" / "configs" / "ppo.py").read_text()


def test_docs_tables_list_every_preset_and_env():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    from experiments import configs
    from jaxarm import envs

    assert [name for name, _ in hooks.preset_rows()] == configs.names()
    assert dict(hooks.env_rows()) == envs.describe()
