"""Every notebook of ``notebooks/`` runs from top to bottom and shows at least one picture.

The notebooks are the user's guide, so each is executed here, in a fresh kernel and a
temporary folder (nothing is written beside the notebook), as ``jupyter nbconvert
--execute`` would; a cell that raises fails the test with the cell's traceback. The
executed notebook must then hold a picture (an ``image/png`` output, from ``Mesh.plot``,
matplotlib or a render of its own): a notebook that only prints numbers fails.

This replaces running the notebooks through ``--nbmake``: the same execution (nbclient),
once, with the picture check added.
"""

from __future__ import annotations

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="the test extra is not installed: pip install -e '.[test]'")
nbclient = pytest.importorskip("nbclient", reason="the test extra is not installed: pip install -e '.[test]'")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
#: seconds one cell may take on a busy 2-core machine before the run is called hung
CELL_TIMEOUT = 900


def pictures(nb) -> int:
    """How many ``image/png`` outputs the notebook's code cells hold."""
    return sum("image/png" in out.get("data", {})
               for cell in nb.cells if cell.cell_type == "code" for out in cell.get("outputs", []))


def test_the_picture_count_reads_outputs_only():
    nb = nbformat.v4.new_notebook(cells=[
        nbformat.v4.new_markdown_cell("![a picture in markdown is not an output](x.png)"),
        nbformat.v4.new_code_cell("1", outputs=[nbformat.v4.new_output("execute_result", data={"text/plain": "1"})]),
    ])
    assert pictures(nb) == 0
    nb.cells[1].outputs.append(nbformat.v4.new_output("display_data", data={"image/png": "iVBORw0KGgo="}))
    assert pictures(nb) == 1


def test_every_notebook_is_found():
    assert len(NOTEBOOKS) >= 8, [p.name for p in NOTEBOOKS]
    assert NOTEBOOKS[0].name == "00_quickstart.ipynb"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_and_shows_a_picture(path, tmp_path):
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:  # executed from scratch: the stored outputs must not count
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:
        pytest.fail(f"{path.name}: a cell raised\n{exc}", pytrace=False)
    assert pictures(nb) >= 1, f"{path.name} ran but shows no picture (an image/png output)"
