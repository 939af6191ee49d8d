"""The notebooks run top to bottom as shipped (nbclient), each in a copy of ``notebooks/`` with
``results/`` beside it, as a user's checkout has them.

Every cell runs as shipped, its settings included (``TASK``, ``METHODS``, ``OUT``, ``RUN_DIRS``,
``FIGURES``). The two that train get one cell more after their settings, as papermill injects
parameters, that shrinks only the run's size (``RUN``, ``OVERRIDES``) to a tiny run; run twice
in the same folder, the quickstart continues its own run instead of failing."""

import csv
import os
import shutil

import nbformat
import pytest
from nbclient import NotebookClient

from tests_support import CACHE_DIR, ROOT, TINY_OVERRIDES, TINY_SIZE

pytestmark = pytest.mark.slow  # each notebook runs in a kernel of its own
NOTEBOOKS = os.path.join(ROOT, "notebooks")
TINY = f"RUN = {TINY_SIZE!r}\nOVERRIDES = {TINY_OVERRIDES!r}"


def _checkout(tmp_path) -> str:
  """A folder laid out as the checkout: notebooks/ (copied) and results/ (linked)."""
  folder = tmp_path / "notebooks"
  if not folder.exists():
    shutil.copytree(NOTEBOOKS, folder)
    os.symlink(os.path.join(ROOT, "results"), tmp_path / "results")
  return str(folder)


def _execute(folder, name, monkeypatch, injected=None):
  """Runs ``folder/name`` as shipped; ``injected``: a cell run right after its settings."""
  nb = nbformat.read(os.path.join(folder, name), as_version=4)
  at = [i for i, c in enumerate(nb.cells) if "parameters" in c.metadata.get("tags", [])]
  assert len(at) == 1
  if injected:
    cell = nbformat.v4.new_code_cell(injected)
    cell.metadata["tags"] = ["injected-parameters"]
    nb.cells.insert(at[0] + 1, cell)
  monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", CACHE_DIR)
  monkeypatch.setenv("PYTHONPATH", ROOT)
  NotebookClient(nb, timeout=600, kernel_name="python3",
                 resources={"metadata": {"path": folder}}).execute()
  return nb


def _outputs(nb, kind):
  return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
          if kind in o.get("data", {})]


def _printed(nb) -> str:
  return "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                 for o in c.get("outputs", []))


@pytest.fixture(scope="module")
def quickstart(tmp_path_factory):
  """The quickstart run twice in one folder: (first run, second run, its OUT)."""
  folder = _checkout(tmp_path_factory.mktemp("checkout"))
  mp = pytest.MonkeyPatch()
  try:
    first = _execute(folder, "quickstart.ipynb", mp, TINY)
    second = _execute(folder, "quickstart.ipynb", mp, TINY)
  finally:
    mp.undo()
  return first, second, os.path.join(folder, "runs", "quickstart")  # its shipped OUT


def test_quickstart_trains_plots_and_renders(quickstart):
  nb, _, out = quickstart
  assert os.path.exists(os.path.join(out, "metrics.csv"))
  assert os.path.exists(os.path.join(out, "ours_seed0.gif"))
  assert len(_outputs(nb, "image/png")) == 4  # success, modes, IQM and per-seed figures
  assert len(_outputs(nb, "image/gif")) == 1
  assert any("| PointMaze | Ours |" in o["data"]["text/markdown"]
             for o in _outputs(nb, "text/markdown"))
  assert "compiling the training program" in _printed(nb)


def test_quickstart_run_again_continues_its_own_run(quickstart):
  first, second, out = quickstart
  printed = _printed(second)
  assert "already trained to step 800" in printed, printed[-2000:]
  with open(os.path.join(out, "metrics.csv"), newline="") as f:
    rows = list(csv.DictReader(f))
  assert len(rows) == 2 * 2 * 4  # 2 methods x 2 seeds x 4 chunks, once
  assert len(_outputs(second, "image/png")) == 4


def test_paper_figures_as_shipped(tmp_path, monkeypatch):
  """Its shipped RUN_DIRS, the committed Ant Push study (run folders one level down)."""
  folder = _checkout(tmp_path)
  nb = _execute(folder, "paper_figures.ipynb", monkeypatch)
  assert len(_outputs(nb, "image/png")) == 4
  figures = os.path.join(folder, "runs", "figures")
  assert {"antpush_iqm.png", "antpush_success.pdf", "summary.md"} <= set(os.listdir(figures))
  assert "| AntPush | Ours |" in "".join(o["data"]["text/markdown"]
                                         for o in _outputs(nb, "text/markdown"))


def test_sweep_notebook_runs_alpha_as_lanes_of_one_program(tmp_path, monkeypatch):
  folder = _checkout(tmp_path)
  nb = _execute(folder, "sweep_alpha.ipynb", monkeypatch, TINY)
  printed = _printed(nb)
  assert "one program, 3 variants x 2 seeds = 6 lanes" in printed, printed[-2000:]
  with open(os.path.join(folder, "runs", "sweep_alpha", "metrics.csv"), newline="") as f:
    methods = {row["method"] for row in csv.DictReader(f)}
  assert len(methods) == 3 and all(m.startswith("ours+top.alpha=") for m in methods), methods
  assert _outputs(nb, "image/png")
  table = "".join(o["data"]["text/markdown"] for o in _outputs(nb, "text/markdown"))
  assert table.count("top.alpha=") == 3, table


def test_runs_of_the_notebooks_are_not_tracked():
  import subprocess
  if subprocess.run(["git", "rev-parse"], cwd=ROOT, capture_output=True).returncode:
    pytest.skip("not a git checkout")
  r = subprocess.run(["git", "check-ignore", "-q", "notebooks/runs/quickstart/metrics.csv"],
                     cwd=ROOT)
  assert r.returncode == 0
