"""Every notebook in notebooks/ runs top to bottom (the walkthroughs are executed, not just stored).

A notebook may have a cell tagged ``parameters`` (papermill's convention) that sets its campaign's size; the
suite replaces it by :data:`SMALL` so that the walkthrough runs its every step on a smaller campaign (3 blades,
one of them unfilmed, 4 synthetic patterns per flank: 48 s against 85 s for its own 6 blades and 10 patterns,
alone on 2 cores).
"""

from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[2] / "notebooks").glob("*.ipynb"))
#: The parameters cell the suite runs instead of each notebook's own (names a notebook does not use are harmless).
SMALL = {"walkthrough.ipynb": "BLADES, KNOWN, SEED, N_PATTERNS = 3, (1, 3), 5, 4"}


def _set_parameters(nb, name: str) -> None:
    cells = [c for c in nb.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
    if name not in SMALL:
        assert not cells, f"{name}: a parameters cell with no small variant in SMALL"
        return
    assert len(cells) == 1, f"{name}: expected one cell tagged 'parameters', found {len(cells)}"
    own = {line.split("=")[0].strip() for line in cells[0].source.splitlines() if "=" in line and line[0] != "#"}
    small = {line.split("=")[0].strip() for line in SMALL[name].splitlines() if "=" in line}
    assert own == small, f"{name}: its parameters {own} differ from the suite's {small}"
    cells[0].source = SMALL[name]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes(path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    _set_parameters(nb, path.name)
    client = nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    client.execute()
