"""docs/tutorial.ipynb runs top to bottom with the installed package (so it cannot rot), and is
kept in git without outputs."""


import nbformat
import pytest
from helpers import REPO
from nbclient import NotebookClient

DOCS = REPO / "docs"


def test_notebook_is_stored_without_outputs():
    nb = nbformat.read(DOCS / "tutorial.ipynb", as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code)
    assert 10 <= len(nb.cells) <= 30


@pytest.mark.slow
def test_tutorial_runs(monkeypatch):
    from helpers import require_shared_data as shared_data

    nb = nbformat.read(DOCS / "tutorial.ipynb", as_version=4)
    monkeypatch.setenv("FACEMOTION_SHARED_DATA", str(shared_data()))
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(DOCS)}}).execute()
    outputs = {i: c.outputs for i, c in enumerate(nb.cells) if c.cell_type == "code"}
    assert all(outputs.values())
    text = "\n".join(o.get("data", {}).get("text/plain", o.get("text", ""))
                     for outs in outputs.values() for o in outs)
    assert "Traceback" not in text
    # Table I has the three datasets and the region map is drawn as an image
    assert "eyebrows" in text and "both" in text
    assert any("image/png" in o.get("data", {}) for outs in outputs.values() for o in outs)
