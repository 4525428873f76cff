"""The research notebooks (notebooks/*.ipynb): stored without outputs, and each one executed
top to bottom with small settings.

Small settings: the test sets ``TORSIONFIT_NOTEBOOK_SMALL=1`` (and, for the measured-data
notebook, ``TORSIONFIT_NOTEBOOK_DECIMATE``); a notebook reads them and says in its text what its
full settings are. A notebook that reads ``../shared/data`` declares it in its metadata
(``"torsionfit": {"needs_shared_data": true}``) and is skipped, with that reason, when the
folder is absent.
"""

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat", reason="the notebook tests need the test extra (nbformat)")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
SHARED_DATA = ROOT.parent / "shared" / "data"
SMALL_SETTINGS = {"TORSIONFIT_NOTEBOOK_SMALL": "1", "TORSIONFIT_NOTEBOOK_DECIMATE": "64"}


def test_there_are_notebooks():
    assert NOTEBOOKS, "no notebooks under notebooks/"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_is_stored_without_outputs(path):
    nb = nbformat.read(path, as_version=4)
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            assert not cell.outputs and cell.execution_count is None, f"{path.name}: cell {i} has outputs stored (strip them)"


#: executed by ``make test-extended`` only, for the suite's time (its diagnose of a measured loop
#: takes 80–100 s); its rendered copy in docs/ is checked against its code here as every other's
EXTENDED_NOTEBOOKS = ("close_the_loop_measured",)


@pytest.mark.slow
@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.extended) if p.stem in EXTENDED_NOTEBOOKS else p
                                  for p in NOTEBOOKS], ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, monkeypatch):
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    if nb.metadata.get("torsionfit", {}).get("needs_shared_data") and not SHARED_DATA.is_dir():
        pytest.skip(f"{path.name} reads measured data from {SHARED_DATA}, which is absent")
    for key, value in SMALL_SETTINGS.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    client = NotebookClient(nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(ROOT / "notebooks")}})
    # raises CellExecutionError, with the cell and its traceback, on any failure; the executed
    # copy is not written back, so the stored notebook stays without outputs
    client.execute()


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_docs_show_an_executed_copy_of_the_current_notebook(path):
    """docs/notebooks/ holds the executed copies the site shows (scripts/render_notebooks.py):
    one per notebook, with outputs, of the notebook's current code (re-render after an edit)."""
    copy = ROOT / "docs" / "notebooks" / path.name
    assert copy.is_file() and not copy.is_symlink(), f"{copy}: run scripts/render_notebooks.py --small"
    stored, rendered = nbformat.read(path, as_version=4), nbformat.read(copy, as_version=4)
    code = [c.source for c in stored.cells if c.cell_type == "code"]
    assert code == [c.source for c in rendered.cells if c.cell_type == "code"], \
        f"{copy} was rendered from an older {path.name}: run scripts/render_notebooks.py --small {path.stem}"
    assert any(c.outputs for c in rendered.cells if c.cell_type == "code"), f"{copy} has no outputs"
