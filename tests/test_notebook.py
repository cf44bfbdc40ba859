"""The example notebook runs from top to bottom in a fresh kernel (nbclient) and shows what it says it shows."""

import os
from pathlib import Path

import pytest

from app.scene.files import ROOT

NOTEBOOK = ROOT / "examples" / "narrow_passages.ipynb"


def tagged(notebook, tag: str):
    (cell,) = (c for c in notebook.cells if tag in c.metadata.get("tags", []))
    return cell


def text_of(cell) -> str:
    return "".join(out.get("text", "") for out in cell.outputs if out.output_type == "stream")


def test_the_example_notebook_runs_and_plans(monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")

    # The kernel inherits this environment: Meshcat allowed (on localhost; conftest's offline Drake cache still
    # stops any download), and matplotlib left to the kernel's inline backend so figures become image outputs.
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")
    monkeypatch.delenv("MPLBACKEND", raising=False)
    # `import app` in the kernel must be this checkout's package, whichever one is installed.
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    assert all(not c.get("outputs") for c in notebook.cells if c.cell_type == "code"), "stored with outputs"

    # python3: the kernelspec ipykernel installs; jupyter_client starts it with this interpreter.
    nbclient.NotebookClient(
        notebook, kernel_name="python3", timeout=120, resources={"metadata": {"path": str(Path(NOTEBOOK).parent)}}
    ).execute()  # raises CellExecutionError on any failing cell

    assert "certified: True" in text_of(tagged(notebook, "plan"))
    assert "Meshcat: http://localhost:" in text_of(tagged(notebook, "meshcat"))
    figure = tagged(notebook, "figure")
    assert any("image/png" in out.get("data", {}) for out in figure.outputs), figure.outputs
