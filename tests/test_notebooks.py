"""Every notebook in notebooks/ runs top to bottom on a fresh install (small default
settings), so the saved notebooks cannot rot.

Each notebook is executed with nbclient in a `python3` kernel whose working directory is
notebooks/ (as when it is opened there); nothing is written back. A failing cell fails
the test with that cell's number, source and error. Without nbclient, nbformat or
ipykernel (the `test` extra) the tests are skipped.
"""

import pathlib
import re

import pytest


NOTEBOOK_DIR = pathlib.Path(__file__).resolve().parent.parent / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
CELL_TIMEOUT = 300  # seconds per cell
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _require(module: str):
    return pytest.importorskip(
        module,
        reason=f"executing the notebooks needs {module}: pip install nbclient "
        "nbformat ipykernel (or the package's `test` extra)",
    )


def _failed_cell(notebook) -> str:
    """The first cell with an error output: its number, source and traceback."""
    for index, cell in enumerate(notebook.cells):
        for output in cell.get("outputs", []):
            if output.get("output_type") == "error":
                trace = _ANSI.sub("", "\n".join(output.get("traceback", [])))
                return (
                    f"cell {index} raised {output.get('ename')}: "
                    f"{output.get('evalue')}\n--- source ---\n{cell.source}\n"
                    f"--- traceback (end) ---\n{trace[-3000:]}"
                )
    return ""


# The jupyter stack (jupyter_client, jupyter_core, zmq, tornado, traitlets) emits
# deprecation and resource warnings of its own while it starts and stops the kernel;
# they are not jaxhyst's and must not trip pytest's `filterwarnings = error`.
# Warnings raised inside the notebooks run in the kernel process and are unaffected.
@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")
@pytest.mark.filterwarnings("ignore::ResourceWarning")
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.filterwarnings("ignore:.*(zmq|jupyter|kernel|event loop).*:RuntimeWarning")
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path):
    nbformat = _require("nbformat")
    nbclient = _require("nbclient")
    _require("ipykernel")
    notebook = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(path.parent)}},
        record_timing=False,
    )
    failure = None
    try:
        client.execute()
    except nbclient.exceptions.CellTimeoutError as error:
        failure = f"a cell ran longer than {CELL_TIMEOUT} s\n{str(error)[-2000:]}"
    except nbclient.exceptions.CellExecutionError as error:
        failure = _failed_cell(notebook) or _ANSI.sub("", str(error))[-3000:]
    if failure is not None:  # outside `except`: no chained kernel traceback
        pytest.fail(f"{path.name} failed: {failure}", pytrace=False)


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 2, "notebooks/ should hold the executed notebooks"
