"""Rules of the source's layout that lint does not state: no module of the runner over 350 lines.

A module grows one concern at a time until a newcomer cannot tell where a change goes (runner/loop.py reached 655
lines of five concerns, runner/rundir.py 530); past the limit, split it by concern.
"""

from pathlib import Path

import jaxarm

RUNNER = Path(jaxarm.__file__).parent / "runner"
MAX_RUNNER_LINES = 350


def test_no_runner_module_is_over_350_lines():
    sizes = {str(path.relative_to(RUNNER)): len(path.read_text().splitlines()) for path in RUNNER.rglob("*.py")}
    assert sizes, f"no modules found under {RUNNER}"
    assert {name: lines for name, lines in sizes.items() if lines > MAX_RUNNER_LINES} == {}
