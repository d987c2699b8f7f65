"""The notebooks under notebooks/ are committed with the outputs of a whole run at their own sizes, and run top
to bottom at their QUICK sizes (JAXARM_NOTEBOOK_QUICK=1) without PYTHONPATH.

Each notebook is executed by nbclient in a fresh kernel ("python3": jupyter_client starts it with the
interpreter running the tests) whose working directory and TMPDIR are the test's temporary directory, so
whatever a notebook writes (run directories, sweep tables) lands there and is cleaned up.

Compiling dominates the notebooks' run time (MJX alone takes 1-2 minutes on 2 CPU cores), so the kernels inherit
the test session's persistent compilation cache (tests/conftest.py) and read back what the other tests compiled.
"""

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
def test_notebook_is_committed_with_the_outputs_of_one_whole_run(path):
    notebook = nbformat.read(path, as_version=4)
    nbformat.validate(notebook)
    counts = [cell.execution_count for cell in notebook.cells if cell.cell_type == "code"]
    assert counts == list(range(1, len(counts) + 1)), f"{path.name}: run it top to bottom once before committing"
    assert not any(
        output.get("output_type") == "error" for cell in notebook.cells for output in cell.get("outputs", [])
    ), f"{path.name} is committed with an error"


@pytest.mark.parametrize("path", notebook_paths(), ids=lambda path: path.stem)
def test_notebook_has_one_parameters_cell(path):
    notebook = nbformat.read(path, as_version=4)
    tagged = [cell for cell in notebook.cells if "parameters" in cell.metadata.get("tags", [])]
    assert len(tagged) == 1 and tagged[0].cell_type == "code", f"{path.name} needs exactly one 'parameters' cell"


@pytest.mark.slow
@pytest.mark.parametrize("path", notebook_paths(), ids=lambda path: path.stem)
def test_notebook_runs_at_its_quick_sizes(path, tmp_path, monkeypatch):
    # The kernel inherits the environment: the notebooks' tempfile directories go to tmp_path and their sizes are
    # the QUICK ones. No PYTHONPATH: each notebook finds the checkout's presets (`experiments`) itself.
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setenv("JAXARM_NOTEBOOK_QUICK", "1")
    monkeypatch.delenv("PYTHONPATH", raising=False)
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(
        notebook, timeout=CELL_TIMEOUT_S, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # raises CellExecutionError naming the failing cell
