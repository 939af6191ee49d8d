"""experiments.plot's statistics: the table (IQM [CI], P(ours > method), mode counts) and the
IQM and ablation figures, and the rows they read (``experiments.curves``) and the look they
share (``experiments.drawing``), from tiny synthetic metrics.csv files (no training)."""

import csv
import os

import numpy as np
import pytest

from experiments import curves, drawing, plot

COLUMNS = (*curves.REQUIRED, *(f"cum_{kind}_after_start_{m}" for kind in ("decisions", "steps")
                              for m in plot.MODES))
STEPS = (100, 200, 300, 400)
# S_E per seed at each evaluation; the first row of each seed comes before any evaluation.
S_E = {
    "ours": [(0.0, 0.2, 1.0), (0.0, 1.0, 1.0), (0.2, 0.6, 1.0), (0.0, 1.0, 0.8), (0.1, 0.3, 0.9)],
    "hiro": [(0.0, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.4, 1.0, 1.0)],
    "ours-no-mods": [(0.0, 0.0, 0.5), (0.0, 0.5, 0.5), (0.0, 0.0, 0.0)],
    "ref-uniform": [(0.0, 0.5, 1.0)] * 3 + [(0.0, 0.0, 0.5)],
    "ref-ppo": [(0.0, 0.0, 0.0)] * 3 + [(0.0, 0.0, 0.5)],
    "ours-no-loss-mod": [(0.0, 1.0, 0.0), (0.6, 0.2, 0.4), (0.0, 0.0, 0.0)],  # two fall back
}


def _write(folder, methods, task="PointMaze"):
  os.makedirs(folder)
  with open(os.path.join(folder, "metrics.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, COLUMNS, lineterminator="\n")
    w.writeheader()
    for m in methods:
      for seed, s_e in enumerate(S_E[m]):
        for i, step in enumerate(STEPS):
          evaluated = i > 0
          w.writerow({
              "task": task, "method": m, "seed": seed, "env_step": step,
              "eval_success": s_e[i - 1] if evaluated else "",
              "eval_return": -10 * (1 - s_e[i - 1]) if evaluated else "",
              **{f"cum_steps_{mode}": step * k for mode, k in zip(plot.MODES, (6, 3, 1))},
              **{f"cum_decisions_after_start_{mode}": step * k // 100 + seed
                 for mode, k in zip(plot.MODES, (6, 3, 1))},
              **{f"cum_steps_after_start_{mode}": step * k // 10 + 10 * seed
                 for mode, k in zip(plot.MODES, (6, 3, 1))}})
  return str(folder)


@pytest.fixture
def runs(tmp_path):
  return [_write(tmp_path / "main", ["ours", "hiro"]), _write(tmp_path / "abl", ["ours-no-mods"])]


def test_summary_gives_iqm_intervals_and_probability_of_improvement(runs):
  table = {r["method"]: r for r in plot.summary(curves.load(runs))}
  ours, hiro, ablation = table["ours"], table["hiro"], table["ours-no-mods"]
  assert (ours["seeds"], ours["env_steps"], ablation["seeds"]) == (5, 400, 3)
  # final S_E of ours: 1, 1, 1, 0.8, 0.9; 5 runs cut 1 at each end: mean(0.9, 1, 1) = 0.967.
  assert ours["final_s_e"][0] == pytest.approx(0.9667, abs=1e-4)
  # best S_E of ours: 1, 1, 1, 1, 0.9 -> mean(1, 1, 1) = 1; of hiro: 0, 0.1, 0, 0, 1 -> 0.033.
  assert ours["best_s_e"][0] == 1.0 and hiro["best_s_e"][0] == pytest.approx(0.1 / 3)
  lower, upper = ours["final_s_e"][1:]
  assert 0.8 <= lower < 0.9667 < upper <= 1.0
  # P(ours > hiro) on final S_E: hiro's four zeros lose to all 5 of ours (20 pairs); hiro's 1
  # ties three of ours (1.5) and beats 0.8 and 0.9: 21.5 / 25 = 0.86.
  assert hiro["p_ours"][0] == pytest.approx(0.86)
  # its interval (2000 bootstrap replicates, seeded): resampling HIRO's one 1 several times
  # pulls it down to 0.58, still above 0.5
  assert hiro["p_ours"][1:] == pytest.approx((0.58, 1.0))
  assert ours["p_ours"] is None
  # early S_E: no evaluation by a quarter of the run (step 100), so the first (step 200):
  # ours 0, 0, 0.2, 0, 0.1 -> mean(0, 0, 0.1); hiro 0, 0, 0, 0, 0.4 -> 0.
  assert ours["early_step"] == hiro["early_step"] == 200
  assert ours["early_s_e"][0] == pytest.approx(0.1 / 3) and hiro["early_s_e"][0] == 0.0
  assert plot._early(np.array([2, 4, 6, 8, 10, 12, 14, 16])) == 1  # 4 <= 16 / 4
  # ours-no-mods ends at 0.5, 0.5, 0: every pair with ours is won by ours.
  assert ablation["p_ours"] == (1.0, 1.0, 1.0)
  assert ablation["reading"] == "Ours above Ours w/o both" and ours["reading"] == "n/a"
  # decisions after the start: TD3 24 + seed, PPO 12 + seed, RANDOM 4 + seed (seeds 0-4):
  # the intervals lie apart and no IQM is 3x the next (26 / 14, 14 / 6 = 2.3)
  assert ours["mode_order"] == "TD3 > PPO > RANDOM"


def test_readings_follow_the_protocol():
  assert plot.reading((0.7, 0.55, 0.9), "ours", "hiro") == "Ours above HIRO"
  assert plot.reading((0.3, 0.1, 0.45), "ours", "hiro") == "HIRO above Ours"
  assert plot.reading((0.6, 0.5, 0.8), "ours", "hiro") == "cannot be told apart"
  counts = {"decisions_after_start_TD3": (90, 80, 100), "decisions_after_start_PPO": (20, 15, 25),
            "decisions_after_start_RANDOM": (18, 10, 22)}
  assert plot.mode_order(counts) == "TD3 >> PPO ~ RANDOM"  # 90 >= 3 x 20, apart; 15-25 / 10-22
  counts["decisions_after_start_RANDOM"] = (40, 26, 50)  # above PPO, apart, 2x
  assert plot.mode_order(counts) == "TD3 > RANDOM > PPO"


def test_ref_uniform_against_ref_ppo(tmp_path):
  rows = curves.load([_write(tmp_path / "refs", ["ref-uniform", "ref-ppo"])])
  (c,) = plot.comparisons(rows)
  # finals 1, 1, 1, 0.5 against 0, 0, 0, 0.5: each of the three 1s beats all four (12); the
  # 0.5 beats three 0s and ties the 0.5 (3.5): 15.5 / 16.
  assert (c["a"], c["b"]) == ("ref-uniform", "ref-ppo") and c["p"][0] == pytest.approx(15.5 / 16)
  assert c["reading"] == "Ref:Uniform above Ref:PPO"
  assert "| PointMaze | Ref:Uniform | Ref:PPO | 0.97 [" in plot.pairs_table([c])
  assert plot.comparisons(curves.load([_write(tmp_path / "one", ["ref-ppo"])])) == []


def test_table_summary_file_and_figures(runs, tmp_path, capsys):
  """One drawing (matplotlib is the slow part): the printed table, summary.md and the files."""
  out = tmp_path / "fig"
  assert plot.main([*runs, "--out", str(out), "--table"]) == 0
  printed = capsys.readouterr().out
  line = next(l for l in printed.splitlines() if l.startswith("| PointMaze | HIRO |"))
  cells = [c.strip() for c in line.strip("|").split("|")]
  assert cells[2:4] == ["5", "400"]
  assert cells[6].endswith("(200)") and cells[7].startswith("0.86 [")
  # mode counts after the starting mode at the last row: TD3 24 + seed decisions for seeds
  # 0-4 (240 + 10 seed env steps), IQM mean(25, 26, 27) = 26 (260), the interval within
  # [24, 28]; PPO 12 + seed, IQM 14 (140); RANDOM 4 + seed, IQM 6 (60).
  assert cells[8] == "Ours above HIRO"  # P 0.86 [0.58, 1.00] (the summary test)
  low, high = (int(x) for x in cells[9].split("[")[1].split("]")[0].split(", "))
  assert cells[9].startswith("26 [") and cells[9].endswith("] (260)") and 24 <= low < high <= 28
  assert cells[10].startswith("14 [") and cells[11].endswith("] (60)")
  assert cells[12] == "TD3 > PPO > RANDOM"
  assert "| PointMaze | Ours | 5 | 400 | 0.97 [" in printed and "| n/a |" in printed
  summary = (out / "summary.md").read_text()
  assert "stratified-bootstrap" in summary and line in summary
  names = sorted(os.listdir(out))
  kinds = ("success", "modes", "iqm", "seeds", "ablation")
  assert names == sorted(f"pointmaze_{kind}.{ext}" for kind in kinds
                         for ext in ("png", "pdf")) + ["summary.md"]
  assert all(str(out / n) in printed for n in names)
  assert all(os.path.getsize(out / n) > 5000 for n in names if n != "summary.md")


def test_iqm_curve_of_a_method(runs):
  steps, point, lower, upper, n = plot.iqm_curves(curves.load(runs), "PointMaze", ["ours"])["ours"]
  # ours at step 200 (the first evaluation): 0, 0, 0.2, 0, 0.1 -> mean(0, 0, 0.1) = 0.033;
  # at 300: 0.2, 1, 0.6, 1, 0.3 -> mean(0.3, 0.6, 1) = 0.633; at 400: 0.967 (above).
  assert list(steps) == [200, 300, 400] and n == 5
  np.testing.assert_allclose(point, [0.1 / 3, 1.9 / 3, 2.9 / 3])
  assert (lower <= point).all() and (point <= upper).all() and (lower < upper).all()


def test_a_results_tree_of_run_folders_loads_every_run(tmp_path):
  # results/<task>/<method>/metrics.csv, as the study lays its runs out
  _write(tmp_path / "pointmaze" / "ours", ["ours"])
  _write(tmp_path / "pointmaze" / "hiro", ["hiro"])
  rows = curves.load([str(tmp_path / "pointmaze")])
  assert {r["method"] for r in rows} == {"ours", "hiro"}
  assert len(rows) == len(STEPS) * (len(S_E["ours"]) + len(S_E["hiro"]))
  with pytest.raises(ValueError, match="not found"):
    curves.load([str(tmp_path / "empty")])


def test_per_seed_table_gives_final_s_e_and_first_success(runs):
  table = plot.seeds_table(curves.load(runs)).splitlines()
  # ours ends at 1, 1, 1, 0.8, 0.9 and first reaches 0.5 at 400, 300, 300, 300, 400
  assert "| PointMaze | Ours | 1, 1, 1, 0.8, 0.9 | 5 of 5 | 0 | 400, 300, 300, 300, 400 |" in table
  assert "| PointMaze | HIRO | 0, 0, 0, 0, 1 | 1 of 5 | 0 | -, -, -, -, 300 |" in table
  # ours-no-mods: seeds 0 and 1 reach 0.5 (at 400, 300) and stay; seed 2 never does
  assert "| PointMaze | Ours w/o both | 0.5, 0.5, 0 | 2 of 3 | 0 | 400, 300, - |" in table


def test_per_seed_table_counts_the_seeds_that_fell_back(tmp_path):
  table = plot.seeds_table(curves.load([_write(tmp_path / "x", ["ours-no-loss-mod"])]))
  assert "| PointMaze | Ours w/o loss mod. | 0, 0.4, 0 | 0 of 3 | 2 | 300, 200, - |" in table


def test_each_task_is_drawn_into_the_first_folder_that_holds_it(tmp_path):
  # results/<task>/<method>/metrics.csv: `plot results/point*` draws each task into its own
  maze, fall = tmp_path / "pointmaze", tmp_path / "pointfall"
  _write(maze / "ours", ["ours"])
  _write(fall / "ours", ["ours"], task="PointFall")
  _write(fall / "hiro", ["hiro"], task="PointFall")
  dirs = [str(fall), str(maze), str(maze / "ours")]
  assert plot.figure_folders(dirs) == {str(fall / "figures"): ["PointFall"],
                                       str(maze / "figures"): ["PointMaze"]}
  assert plot.figure_folders(dirs, out="figs") == {"figs": ["PointFall", "PointMaze"]}


def test_drawing_the_same_figure_twice_writes_the_same_bytes(tmp_path):
  """Committed figures change only when their data does: the same figure drawn in two
  processes (a date, a random id or a process's state would show) gives the same bytes, and
  the PDF carries no creation date."""
  import subprocess
  import sys
  draw = ("import sys, matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot as plt; "
          "from experiments import drawing; fig, ax = plt.subplots(figsize=(2, 2)); "
          "ax.plot([0, 1], [0, 1]); drawing.finish(fig, sys.argv[1], 'fig')")
  root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
  for name in ("a", "b"):
    (tmp_path / name).mkdir()
    subprocess.run([sys.executable, "-c", draw, str(tmp_path / name)], cwd=root, check=True,
                   env={**os.environ, "PYTHONPATH": root})
  assert b"/CreationDate" not in (tmp_path / "a" / "fig.pdf").read_bytes()
  for ext in ("png", "pdf"):
    a, b = (tmp_path / name / f"fig.{ext}" for name in ("a", "b"))
    assert a.read_bytes() == b.read_bytes()


def test_folders_of_a_job_array_merge_their_seeds(tmp_path):
  """Independent runs of one method (a job array, --seed 0, 1) in separate folders: their
  seeds add up in the table and figures, they do not overwrite each other."""
  from nonmono_jax.host import rows as rows_lib
  for k in range(2):
    d = tmp_path / f"run{k}"
    d.mkdir()
    rows = []
    for step in (2000, 4000):
      for seed in range(3):
        row = {c: "" for c in rows_lib.COLUMNS}
        row.update(task="PointMaze", method="ours", seed=seed, env_step=step,
                   eval_success=float(k), eval_return=-1.0,
                   **{f"cum_steps_{m}": 10 for m in plot.MODES})
        rows.append(row)
    with open(d / "metrics.csv", "w", newline="") as f:
      w = csv.DictWriter(f, fieldnames=rows_lib.COLUMNS)
      w.writeheader()
      w.writerows(rows)
  rows = curves.load([str(tmp_path / "run0"), str(tmp_path / "run1")])
  steps, values = curves.per_seed(rows, "PointMaze", "ours", "eval_success")
  assert values.shape == (6, 2) and list(values[:, -1]) == [0, 0, 0, 1, 1, 1]
  assert curves.seed_ids(rows, "PointMaze", "ours") == ["0", "1", "2", "1/0", "1/1", "1/2"]
  (r,) = plot.summary(rows, reps=100)
  assert r["seeds"] == 6


def test_seeds_come_in_numeric_order(tmp_path, monkeypatch):
  """Seed 10 comes after seed 9, not after seed 1: the per-seed table and figure list seeds
  in the order they were run."""
  monkeypatch.setitem(S_E, "twelve", [(0.0, 0.0, k / 20) for k in range(12)])
  rows = curves.load([_write(tmp_path / "x", ["twelve"])])
  assert curves.seed_ids(rows, "PointMaze", "twelve") == [str(k) for k in range(12)]
  steps, values = curves.per_seed(rows, "PointMaze", "twelve", "eval_success")
  assert list(values[:, -1]) == [k / 20 for k in range(12)]
  # a seed with a value only at a step the others have not reached stays out of both
  rows.append({**rows[-1], "seed": "12", "env_step": "500"})
  assert curves.seed_ids(rows, "PointMaze", "twelve") == [str(k) for k in range(12)]
  assert curves.per_seed(rows, "PointMaze", "twelve", "eval_success")[1].shape == (12, 3)


def test_env_step_axes_read_in_thousands_and_millions(tmp_path):
  """Six-digit step ticks (100000, 125000, ...) run into each other on the Ant's 1M runs: a
  step axis reads 200k, 1M."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  fig, (steps_ax, other_ax) = plt.subplots(1, 2)
  for ax in (steps_ax, other_ax):
    ax.plot([0, 1_000_000], [0, 1])
  steps_ax.set_xlabel(drawing.STEPS_LABEL)
  drawing.finish(fig, str(tmp_path), "fig")
  fig.canvas.draw()
  assert {"200k", "1M"} <= {t.get_text() for t in steps_ax.get_xticklabels()}
  assert "1M" not in [t.get_text() for t in other_ax.get_xticklabels()]
  plt.close(fig)


def test_seeds_figure_wraps_its_panels_and_names_few_seeds(tmp_path, monkeypatch):
  """Six methods draw two rows of panels (four, then two) rather than one strip six panels
  wide; a panel names its seeds in a legend only while they are few enough to read."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  monkeypatch.setitem(S_E, "many", [(0.0, 0.0, k / 20) for k in range(plot.SEEDS_LEGEND + 1)])
  methods = ["ours", "hiro", "ref-uniform", "ref-ppo", "ours-no-mods", "many"]
  rows = curves.load([_write(tmp_path / "x", methods)])
  figures = []
  monkeypatch.setattr(plot, "finish", lambda fig, out, name, *_: figures.append(fig) or [])
  plot._seeds_figure(plt, rows, "PointMaze", methods, str(tmp_path))
  (fig,) = figures  # closed by now; its axes stay readable
  fig.canvas.draw()
  shown = [ax for ax in fig.axes if ax.get_visible()]
  assert len(fig.axes) == 8 and [ax.get_title() for ax in shown] == [
      f"{drawing.label(m)} ({len(S_E[m])} seeds)" for m in methods]
  assert {round(ax.get_position().y0, 2) for ax in shown[:4]} != {
      round(ax.get_position().y0, 2) for ax in shown[4:]}  # a second row
  assert [ax.get_legend() is not None for ax in shown] == [True] * 5 + [False]


def test_the_papers_axis_counts_from_the_end_of_warm_up(tmp_path):
  """``--axis paper``: env step minus each run's warm-up (its config.json), the paper's x-axis
  (its code logs at t - start_timestep); the first Ant Push study's first evaluation, at env
  step 110K, is the paper's 10K, its last at 1M the paper's 900K."""
  here = os.path.dirname(os.path.abspath(__file__))
  study = os.path.join(here, "..", "results", "antpush")
  env_rows, paper_rows = curves.load([study]), curves.load([study], axis="paper")
  evaluated = lambda rows: sorted({int(r["env_step"]) for r in rows if r["eval_success"]})
  assert evaluated(env_rows)[0] == 110_000 and evaluated(paper_rows)[0] == 10_000
  assert max(evaluated(paper_rows)) == max(evaluated(env_rows)) - 100_000 == 900_000
  assert len(paper_rows) < len(env_rows)  # the warm-up's rows are left out
  run = tmp_path / "run"
  run.mkdir()
  (run / "metrics.csv").write_text(open(os.path.join(study, "ours", "metrics.csv")).read())
  with pytest.raises(ValueError, match="the paper's axis needs each run's warm-up"):
    curves.load([str(run)], axis="paper")
  out = plot.plot([os.path.join(study, "ours")], str(tmp_path / "fig"), axis="paper")
  assert any(p.endswith("antpush_iqm.png") for p in out)


# --- what a reader of the figures is told (issue 51) ------------------------------------------

def _figure_of(monkeypatch, draw, *args):
  """The figure ``draw(plt, *args, out)`` makes (``finish`` intercepted, nothing written)."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  figures = []
  monkeypatch.setattr(plot, "finish", lambda fig, out, name, *_: figures.append(fig) or [])
  draw(plt, *args, "unused")
  (fig,) = figures
  fig.canvas.draw()
  return fig


def test_success_bands_are_intervals_clipped_to_one_and_the_legend_covers_nothing(
    tmp_path, monkeypatch):
  monkeypatch.setitem(S_E, "one", [(0.0, 1.0, 1.0)])
  rows = curves.load([_write(tmp_path / "x", ["ours", "hiro", "one"])])
  fig = _figure_of(monkeypatch, plot._success_figure, rows, "PointMaze", ["ours", "hiro", "one"])
  ax = fig.axes[0]
  assert "95% CI" in ax.get_title() and ax.get_ylabel() == "success rate (evaluation)"
  for band in ax.collections:
    ys = np.concatenate([p.vertices[:, 1] for p in band.get_paths()])
    assert ys.min() >= 0 and ys.max() <= 1
  assert ax.get_legend() is None and len(fig.legends) == 1  # below the panels
  labels = [t.get_text() for t in fig.legends[0].get_texts()]
  assert "One (1 seed)" in labels or any(l.endswith("(1 seed)") for l in labels), labels
  legend_top = fig.legends[0].get_window_extent().y1
  assert legend_top <= ax.get_window_extent().y0  # under the axes, not on a curve


def test_a_mode_never_chosen_is_named_and_drawn_in_its_own_style(tmp_path, monkeypatch):
  rows = curves.load([_write(tmp_path / "x", ["ours", "hiro"])])
  for r in rows:  # HIRO runs TD3 only: its PPO and RANDOM lines lie on 0, one over the other
    if r["method"] == "hiro":
      r["cum_steps_PPO"] = r["cum_steps_RANDOM"] = "0"
  fig = _figure_of(monkeypatch, plot._modes_figure, rows, "PointMaze", ["ours", "hiro"])
  hiro = fig.axes[1]
  styles = {l.get_label(): l.get_linestyle() for l in hiro.get_lines()}
  assert len(set(styles.values())) == 3, styles
  texts = [t.get_text() for t in hiro.texts]
  assert texts == ["never chosen: PPO, RANDOM"], texts


def test_too_few_seeds_for_an_interval_is_said(tmp_path, monkeypatch):
  """Four seeds that end at 0 or 1: the IQM's bootstrap interval spans [0, 1] and says nothing;
  the summary names it."""
  monkeypatch.setitem(S_E, "ours", [(0.0, 0.0, 1.0), (0.0, 1.0, 1.0), (0.0, 0.0, 0.0),
                                    (0.0, 0.0, 0.0)])
  rows = curves.load([_write(tmp_path / "x", ["ours"])])
  (r,) = plot.summary(rows)
  assert plot.uninformative(r["final_s_e"])
  note = plot.too_few_note([r])
  assert note.startswith("Too few seeds for an interval") and "Ours (4 seeds" in note
  assert "Too few seeds for an interval" in plot.tables(rows)
  assert drawing.seeds_text(1) == "1 seed" and drawing.seeds_text(4) == "4 seeds"


def test_the_gif_has_a_key_for_its_marks(tmp_path):
  import envs
  from experiments import render
  env = envs.make("PointMaze", episode_length=10)
  n = 4
  roll = {"env": env, "pos": np.zeros((n, 3)), "goal": np.ones((n, 3)),
          "blocks": np.zeros((n, 0, 3)), "success": np.zeros(n, bool), "task": "PointMaze",
          "method": "ours", "seed": 0, "step": 100, "num_envs": 1}
  assert render.draw(roll, str(tmp_path / "a.gif"), max_frames=2) == 2
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  fig, ax = plt.subplots()
  labels = render.key(ax)
  assert labels == ["robot", "its path", "Middle's goal", "target, its radius", "block", "chasm",
                    "wall"]
  assert [t.get_text() for t in ax.get_legend().get_texts()] == labels
  plt.close(fig)
