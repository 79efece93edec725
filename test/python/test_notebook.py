"""The design-study notebook (docs/design_study.ipynb) runs from top to bottom with the built package, so it can
never go stale: executed here with nbclient in a fresh kernel, every cell without an error, every figure drawn."""
import os

import nbclient
import nbformat

DOCS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "docs")


def test_design_study_notebook_executes():
    nb = nbformat.read(os.path.join(DOCS, "design_study.ipynb"), as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": DOCS}}).execute()
    images = sum(1 for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {}))
    assert images == 4
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    assert "limit_cycle error 0.051473 rad, period 12.2302 s" in text  # the thesis' App. D1 cycle
