"""The notebook story (issue 29, item 7): examples/rccl_notebook.ipynb run cell by cell in a Jupyter
kernel (nbclient): the arm opens against a real simula, the live 3D view is shown inline (an
IFrame of the view's page, which answers while the notebook runs), the arm reaches its targets,
and both errors arrive as exceptions the notebook catches; the kernel survives them."""
from __future__ import annotations

import re
import urllib.request
from pathlib import Path

import nbformat
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parent.parent / "examples" / "rccl_notebook.ipynb"


def _text(cell) -> str:
    out = []
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream":
            out.append(o["text"])
        elif "data" in o:
            out.append(o["data"].get("text/html", "") + o["data"].get("text/plain", ""))
    return "".join(out)


def test_the_notebook_runs_and_shows_the_arm():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOK.parent)}})
    page = None
    with client.setup_kernel():
        for index, cell in enumerate(nb.cells):
            if cell.cell_type != "code":
                continue
            client.execute_cell(cell, index)          # raises CellExecutionError on an uncaught exception
            errors = [o for o in cell.outputs if o.get("output_type") == "error"]
            assert not errors, errors
            if "IFrame(" in cell.source:
                html = _text(cell)
                url = re.search(r'src="(http://127\.0\.0\.1:\d+/?)"', html).group(1)
                with urllib.request.urlopen(url, timeout=10) as r:     # the live view answers
                    page = r.read().decode("utf-8", "replace")
    assert page is not None and "<html" in page.lower()
    code = [c for c in nb.cells if c.cell_type == "code"]
    moves = _text(next(c for c in code if "for k, p in enumerate(targets)" in c.source))
    distances = [float(x) for x in re.findall(r"([\d.]+) mm from the target", moves)]
    assert len(distances) == 3 and max(distances) < 1.0, moves
    refused = _text(next(c for c in code if "UnreachableTarget" in c.source))
    assert "refused: move(far)" in refused and "still in control: True" in refused
    ended = _text(next(c for c in code if "ControlTerminated as e" in c.source))
    assert "control ended:" in ended and "code 0x1001" in ended and "still in control: False" in ended
    assert "back at park, joints (deg): [   0.   90. -180.    0.  -90." in ended
