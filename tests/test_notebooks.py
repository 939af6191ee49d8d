"""The notebooks run top to bottom (nbclient), with their settings cell swapped for a tiny run."""

import csv
import os

import nbformat
import pytest
from nbclient import NotebookClient

from tests_support import CACHE_DIR, ROOT, TINY_OVERRIDES, TINY_SIZE

pytestmark = pytest.mark.slow  # each notebook runs in a kernel of its own
NOTEBOOKS = os.path.join(ROOT, "notebooks")


def _execute(name, parameters, monkeypatch):
  nb = nbformat.read(os.path.join(NOTEBOOKS, name), as_version=4)
  cells = [c for c in nb.cells if "parameters" in c.metadata.get("tags", [])]
  assert len(cells) == 1
  cells[0].source = parameters
  monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", CACHE_DIR)
  monkeypatch.setenv("PYTHONPATH", ROOT)
  NotebookClient(nb, timeout=600, kernel_name="python3",
                 resources={"metadata": {"path": NOTEBOOKS}}).execute()
  return nb


def _outputs(nb, kind):
  return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
          if kind in o.get("data", {})]


@pytest.fixture(scope="module")
def quickstart(tmp_path_factory):
  out = str(tmp_path_factory.mktemp("nb") / "run")
  mp = pytest.MonkeyPatch()
  try:
    nb = _execute("quickstart.ipynb", f'TASK = "PointMaze"\nMETHODS = ["ours", "hiro"]\n'
                  f'OUT = {out!r}\nRUN = {TINY_SIZE!r}\nOVERRIDES = {TINY_OVERRIDES!r}', mp)
  finally:
    mp.undo()
  return nb, out


def test_quickstart_trains_plots_and_renders(quickstart):
  nb, out = quickstart
  assert os.path.exists(os.path.join(out, "metrics.csv"))
  assert os.path.exists(os.path.join(out, "ours_seed0.gif"))
  assert len(_outputs(nb, "image/png")) == 4  # success, modes, IQM and per-seed figures
  assert len(_outputs(nb, "image/gif")) == 1
  assert any("| PointMaze | Ours |" in o["data"]["text/markdown"]
             for o in _outputs(nb, "text/markdown"))


def test_paper_figures_from_a_results_folder(quickstart, tmp_path, monkeypatch):
  _, out = quickstart
  figures = str(tmp_path / "figs")
  nb = _execute("paper_figures.ipynb", f"RUN_DIRS = [{out!r}]\nFIGURES = {figures!r}",
                monkeypatch)
  assert len(_outputs(nb, "image/png")) == 4
  assert sorted(os.listdir(figures))[:2] == ["pointmaze_iqm.pdf", "pointmaze_iqm.png"]
  assert "summary.md" in os.listdir(figures)


def test_sweep_notebook_runs_alpha_as_lanes_of_one_program(tmp_path, monkeypatch):
  out = str(tmp_path / "sweep")
  sweep = {"top.alpha": [(0.0, 0.4, 0.7), (0.0, 0.8, 1.4)]}
  nb = _execute("sweep_alpha.ipynb", f'TASK = "PointMaze"\nOUT = {out!r}\nRUN = {TINY_SIZE!r}\n'
                f'OVERRIDES = {TINY_OVERRIDES!r}\nSWEEP = {sweep!r}', monkeypatch)
  printed = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                    for o in c.get("outputs", []))
  assert "one program, 2 variants x 2 seeds = 4 lanes" in printed, printed[-2000:]
  with open(os.path.join(out, "metrics.csv"), newline="") as f:
    methods = {row["method"] for row in csv.DictReader(f)}
  assert len(methods) == 2 and all(m.startswith("ours+top.alpha=") for m in methods), methods
  assert _outputs(nb, "image/png")
  table = "".join(o["data"]["text/markdown"] for o in _outputs(nb, "text/markdown"))
  assert table.count("top.alpha=") == 2, table
