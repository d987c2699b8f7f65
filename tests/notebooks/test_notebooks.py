"""The notebooks under notebooks/ run top to bottom with their small default parameters, and carry no outputs.

Each notebook is executed by nbclient in a fresh kernel ("python3": jupyter_client starts it with the
interpreter running the tests) whose working directory and TMPDIR are the test's temporary directory, so
whatever a notebook writes (run directories, sweep tables) lands there and is cleaned up.

Compiling dominates the notebooks' run time (MJX alone takes 1-2 minutes on 2 CPU cores), so the kernels inherit
the test session's persistent compilation cache (tests/conftest.py) and read back what the other tests compiled.
"""

import os
import pathlib

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = pathlib.Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"
CELL_TIMEOUT_S = 600
"""Per cell. The longest cell (MJX's first compile of the Panda sorter) takes about 2 minutes on 2 busy cores."""


def notebook_paths() -> list[pathlib.Path]:
    return sorted(NOTEBOOKS.glob("*.ipynb"))


def test_the_notebooks_are_there():
    names = {path.name for path in notebook_paths()}
    assert {"01_arm2d.ipynb", "02_panda_sort.ipynb", "03_sweeps.ipynb", "04_library_loop.ipynb"} <= names


@pytest.mark.parametrize("path", notebook_paths(), ids=lambda path: path.stem)
def test_notebook_is_committed_without_outputs(path):
    notebook = nbformat.read(path, as_version=4)
    nbformat.validate(notebook)
    for index, cell in enumerate(notebook.cells):
        if cell.cell_type == "code":
            assert cell.outputs == [], f"{path.name} cell {index} has outputs: clear them before committing"
            assert cell.execution_count is None, f"{path.name} cell {index} has an execution count"


@pytest.mark.parametrize("path", notebook_paths(), ids=lambda path: path.stem)
def test_notebook_has_one_parameters_cell(path):
    notebook = nbformat.read(path, as_version=4)
    tagged = [cell for cell in notebook.cells if "parameters" in cell.metadata.get("tags", [])]
    assert len(tagged) == 1 and tagged[0].cell_type == "code", f"{path.name} needs exactly one 'parameters' cell"


@pytest.mark.slow
@pytest.mark.parametrize("path", notebook_paths(), ids=lambda path: path.stem)
def test_notebook_runs_with_its_default_parameters(path, tmp_path, monkeypatch):
    # The kernel inherits the environment: the notebooks' tempfile directories go to tmp_path, and the checkout's
    # root is on its path, as in a Jupyter started there (the presets, `experiments`, are not installed).
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(
        notebook, timeout=CELL_TIMEOUT_S, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # raises CellExecutionError naming the failing cell
