"""The decisive Ant Push study's readings (experiments/sidebyside.py) on made-up runs: the
reference harness's folders and our run folders, written as each writes them."""

import csv
import json
import os

import numpy as np
import pytest

from experiments import claims, plot, sidebyside
from nonmono_jax.host import rows as rows_lib

WARMUP = 100_000


def _reference(folder, seed, s_e, low=-3.0, counts=(100, 5000, 50), until=1_000_000):
  """A harness run folder: evaluations every 10K (x from 10K), windows every 5K."""
  os.makedirs(folder)
  with open(os.path.join(folder, "config.json"), "w") as f:
    json.dump({"seed": seed, "start_timestep": WARMUP}, f)
  with open(os.path.join(folder, "evaluations.csv"), "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["t", "step", "success_rate", "higher_success_rate", "final_distance"])
    for x in range(10_000, until + 1, 10_000):
      w.writerow([x + WARMUP, x, s_e(x), 0.0, 19.0 * (1 - s_e(x))])
  with open(os.path.join(folder, "windows.csv"), "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["t", "step", "low_intrinsic_reward_mean", "on_policy_count",
                "off_policy_count", "random_policy_count", "subgoal_progress"])
    for x in range(-WARMUP + 5000, until + 1, 5000):
      frac = max(x, 0) / until
      w.writerow([x + WARMUP, x, low, *(int(c * frac) for c in counts), 0.5])


def _ours(folder, per_seed, low=-3.0, until=1_000_000, method="ours"):
  """Our run folder: a row per seed every 10K env steps, evaluated from x = 10K."""
  os.makedirs(folder)
  with open(os.path.join(folder, "config.json"), "w") as f:
    json.dump({"configs": {method: {"warmup_steps": WARMUP, "num_envs": 1}}}, f)
  with open(os.path.join(folder, "metrics.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, rows_lib.COLUMNS, extrasaction="ignore")
    w.writeheader()
    for env_step in range(10_000, WARMUP + until + 1, 10_000):
      x = env_step - WARMUP
      for seed, s_e in enumerate(per_seed):
        w.writerow({"task": "AntPush", "method": method, "seed": seed, "env_step": env_step,
                    "eval_success": s_e(x) if x > 0 else "", "eval_return": -1000,
                    "eval_distance": 19.0 * (1 - s_e(x)), "low_reward": low,
                    "low_subgoal_progress": 0.25,
                    **{f"cum_steps_{m}": 0 for m in ("TD3", "PPO", "RANDOM")},
                    **{f"cum_decisions_{m}": c * max(x, 0) // until
                       for m, c in (("TD3", 6000), ("PPO", 1000), ("RANDOM", 2500))}})


def _ramp(level, start=500_000):
  return lambda x: round(level * min(max(x - start, 0) / 300_000, 1.0), 3)


def _write_study(tmp_path, ref_levels, our_levels, until=1_000_000, ref_until=None):
  """The study's folders under ``tmp_path``: a reference folder per level, ours' seeds."""
  for i, level in enumerate(ref_levels):
    _reference(str(tmp_path / "reference" / f"seed{i}"), i, _ramp(level),
               until=ref_until or until)
  _ours(str(tmp_path / "ours"), [_ramp(level) for level in our_levels], until=until)


def _study(tmp_path, ref_levels, our_levels, until=1_000_000):
  _write_study(tmp_path, ref_levels, our_levels, until)
  return sidebyside.readings(sidebyside.load([str(tmp_path)]), reps="exact")


def test_both_learning_alike_reads_as_like_the_reference(tmp_path):
  r = _study(tmp_path, [0.8, 0.75, 0.85], [0.8, 0.7, 0.9, 0.75, 0.85, 0.8])
  assert r["r1"]["reading"] == r["r2"]["reading"] == "holds"
  assert r["r3"]["reading"] == "like the reference (within +-0.2)"
  assert r["r1"]["seeds"] == ["0", "1", "2"] and r["r3"]["seeds"] == (6, 3)
  assert abs(r["r5"]["low_reward", 1_000_000]["difference"][0]) < 1e-9
  assert r["r5"]["low_subgoal_progress", 200_000]["difference"][0] == pytest.approx(-0.25)
  assert np.mean(r["r6"]["reference"]["TD3"]) == 5000
  text = sidebyside.markdown(r)
  assert "| R1. the code's S_E at x = 1M, mean over seeds, passes 0.6 | holds |" in text


def test_the_reference_learning_where_ours_does_not(tmp_path):
  r = _study(tmp_path, [0.8, 0.75, 0.85], [0.0, 0.0, 0.1, 0.0, 0.0, 0.0])
  assert r["r1"]["reading"] == "holds" and r["r2"]["reading"] == "does not hold"
  assert r["r3"]["reading"] == "ours below by more than 0.2"
  assert r["r4"]["difference"][1] > 0  # ours ends farther from the target


def test_neither_learning_is_equivalent_and_says_nothing_of_the_paper(tmp_path):
  """Both at 0: within the margin (the study then reads that neither reproduces here)."""
  r = _study(tmp_path, [0.0, 0.0, 0.0], [0.0] * 6)
  assert r["r1"]["reading"] == "does not hold"
  assert r["r3"]["reading"] == "like the reference (within +-0.2)"


def test_one_reference_seed_of_three_learning_cannot_be_told_apart(tmp_path):
  r = _study(tmp_path, [0.9, 0.0, 0.0], [0.0] * 6)
  assert r["r1"]["reading"] == "cannot be told apart"
  assert r["r3"]["reading"] == "cannot be told apart"


def test_runs_still_going_are_read_only_where_both_got(tmp_path):
  r = _study(tmp_path, [0.8, 0.8, 0.8], [0.8] * 6, until=600_000)
  assert r["r1"]["reading"] == "n/a (x = 1000000 not reached)"
  assert r["r3"]["reading"] == ("n/a (ours: x = 1000000 not reached; the code: x = 1000000 "
                                "not reached)")
  assert sorted({x for _, x in r["r5"]}) == [200_000, 500_000]
  assert r["r6"]["ours"] == {"why": "0 of the protocol's 6 seeds at x = 1000000"}
  assert "| R4. final distance to the target, late (described) | | n/a (ours: x" in (
      sidebyside.markdown(r))


def test_a_seed_short_of_the_protocols_evaluations_is_not_read(tmp_path):
  """Every reading is made on the protocol's seeds, each with every evaluation it uses: a
  reference seed that stopped at 950K, or lacks its evaluation at 1M, or a missing seed, leaves
  R1 and R3 n/a, naming the seeds (the two others alone would read "holds")."""
  _write_study(tmp_path, [0.8, 0.8], [0.8] * 6)
  _reference(str(tmp_path / "reference" / "seed2"), 2, _ramp(0.1), until=950_000)
  r = sidebyside.readings(sidebyside.load([str(tmp_path)]), reps="exact")
  assert r["r1"]["reading"] == "n/a (seed 2 without every value of 1000000-1000000)"
  assert r["r3"]["reading"] == ("n/a (the code: seed 2 without every value of "
                                "900000-1000000)")
  assert r["r2"]["reading"] == "holds"
  assert r["r6"]["reference"] == {"why": "2 of the protocol's 3 seeds at x = 1000000"}
  other = tmp_path / "two"
  _write_study(other, [0.8, 0.8], [0.8] * 6)
  r = sidebyside.readings(sidebyside.load([str(other)]), reps="exact")
  assert r["r1"]["reading"] == "n/a (2 of the protocol's 3 seeds)"
  for seed in (2, 3):  # two seeds just started: their folders hold no rows yet
    folder = other / "reference" / f"seed{seed}"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps({"seed": seed}))
    (folder / "evaluations.csv").write_text("")
    (folder / "windows.csv").write_text("")
  r = sidebyside.readings(sidebyside.load([str(other)]), reps="exact")
  assert r["r1"]["reading"] == "n/a (2 of the protocol's 3 seeds)"


def test_a_copy_of_a_reference_seed_and_a_broken_line_are_refused(tmp_path):
  _write_study(tmp_path, [0.8, 0.8, 0.8], [0.8] * 6)
  _reference(str(tmp_path / "old" / "seed0"), 0, _ramp(0.4))
  with pytest.raises(ValueError, match="both the reference's seed 0"):
    sidebyside.load([str(tmp_path)])
  evaluations = tmp_path / "reference" / "seed1" / "evaluations.csv"
  lines = evaluations.read_text().splitlines()
  evaluations.write_text("\n".join(lines[:-1] + ["1100000,1000000,0.8"]) + "\n")  # half-written
  assert len(sidebyside.reference_rows(str(evaluations.parent))) == len(
      sidebyside.reference_rows(str(tmp_path / "reference" / "seed2"))) - 1
  evaluations.write_text("\n".join(lines[:5] + ["60000,50000,0.8,0.0,nan"] + lines[6:]) + "\n")
  with pytest.raises(ValueError, match="line 6 is malformed or not finite"):
    sidebyside.reference_rows(str(evaluations.parent))


def test_a_difference_on_the_margin_is_on_it():
  """0 against 0.2 is -0.2 to rounding: within the margin, not beyond it."""
  assert sidebyside.equivalence((-0.2 - 4e-17, -0.2 - 4e-17, -0.2 - 4e-17)) == (
      "ours below, by less than 0.2")
  assert sidebyside.versus_level((0.6 - 1e-16, 0.6 - 1e-16, 0.6 - 1e-16), 0.6) == "holds"


def test_claims_picks_the_study_by_its_folders(tmp_path, capsys):
  _study(tmp_path, [0.8, 0.75, 0.85], [0.8, 0.7, 0.9, 0.75, 0.85, 0.8])
  assert sidebyside.is_study([str(tmp_path)])
  assert claims.main([str(tmp_path), "--reps", "exact"]) == 0
  out = capsys.readouterr().out
  assert "the paper's code (reference) and ours" in out and "every resample (exact)" in out
  with pytest.raises(ValueError, match="no reference runs and no run folders"):
    sidebyside.load([str(tmp_path / "empty")])


def test_equivalence_readings():
  assert sidebyside.equivalence((0.0, -0.1, 0.1)) == "like the reference (within +-0.2)"
  assert sidebyside.equivalence((-0.1, -0.15, -0.05)) == "ours below, by less than 0.2"
  assert sidebyside.equivalence((-0.5, -0.6, -0.3)) == "ours below by more than 0.2"
  assert sidebyside.equivalence((-0.3, -0.4, -0.1)) == "ours below"
  assert sidebyside.equivalence((0.0, -0.3, 0.4)) == "cannot be told apart"
  assert sidebyside.equivalence((0.5, 0.3, 0.6)) == "ours above by more than 0.2"


FIGURE_FILES = [f"{sidebyside.FIGURE}.pdf", f"{sidebyside.FIGURE}.png"]  # sorted


def test_plot_draws_the_study_figure_with_hiro(tmp_path, capsys):
  """``experiments.plot`` on the study's folder: its figure, into DIR/figures by default
  (``--table``: its readings)."""
  _write_study(tmp_path, [0.8, 0.75, 0.85], [0.8, 0.7, 0.9, 0.75, 0.85, 0.8])
  _ours(str(tmp_path / "hiro"), [_ramp(0.3)] * 3, method="hiro")
  assert plot.main([str(tmp_path)]) == 0
  assert sorted(os.listdir(tmp_path / "figures")) == FIGURE_FILES
  printed = sorted(capsys.readouterr().out.split())
  assert printed == [str(tmp_path / "figures" / f) for f in FIGURE_FILES]
  rows = sidebyside.load([str(tmp_path)])
  assert sidebyside.figure_label(rows, "hiro") == "HIRO (3 seeds)"
  assert sidebyside.figure_label(rows, "reference") == "The paper's code (3 seeds)"
  assert "the paper's code (reference) and ours" in plot._table_text([str(tmp_path)], None)
  assert plot.main([str(tmp_path), "--axis", "paper", "--out", str(tmp_path / "p")]) == 0
  with pytest.raises(SystemExit) as err:  # its one axis is the paper's: said, not ignored
    plot.main([str(tmp_path), "--axis", "env"])
  assert err.value.code == 2
  assert "drawn on the paper's axis" in capsys.readouterr().err


def test_figure_of_a_study_still_going_without_hiro(tmp_path):
  """The reference behind ours (and its seeds apart): each drawn as far as it got."""
  _write_study(tmp_path, [0.8, 0.8], [0.8] * 6, until=600_000, ref_until=300_000)
  _reference(str(tmp_path / "reference" / "seed2"), 2, _ramp(0.8), until=100_000)
  rows = sidebyside.load([str(tmp_path)])
  paths = sidebyside.figures(rows, str(tmp_path / "out"), reps=20)
  assert sorted(os.path.basename(p) for p in paths) == FIGURE_FILES
  curves = sidebyside.panel_curves(rows, "eval_success", reps=20)
  assert set(curves) == {"reference", "ours"}
  assert curves["reference"][0][-1] == 100_000 and curves["ours"][0][-1] == 600_000
  assert sidebyside.seed_lines(rows, "reference", "eval_success")["0"][0][-1] == 300_000


def test_figure_leaves_out_a_method_without_a_column(tmp_path):
  """No HIRO; the reference without the Low's progress: panel (d) draws ours alone, and
  without it anywhere panel (d) goes."""
  _write_study(tmp_path, [0.8, 0.75, 0.85], [0.8] * 6)
  rows = [{k: v for k, v in r.items() if not (k == "low_subgoal_progress"
                                               and r["method"] == "reference")}
          for r in sidebyside.load([str(tmp_path)])]
  assert set(sidebyside.panel_curves(rows, "low_subgoal_progress", reps=20)) == {"ours"}
  assert len(sidebyside.figures(rows, str(tmp_path / "a"), reps=20)) == 2
  rows = [{k: v for k, v in r.items() if k != "low_subgoal_progress"} for r in rows]
  assert sidebyside.panel_curves(rows, "low_subgoal_progress", reps=20) == {}
  assert len(sidebyside.figures(rows, str(tmp_path / "b"), reps=20)) == 2


def test_the_success_panel_is_the_mean_of_the_seeds(tmp_path):
  """Panel (a)'s reference curve at an evaluation is the mean of its seeds' S_E there, its
  band around it within [0, 1]."""
  _write_study(tmp_path, [0.8, 0.5, 0.2], [0.8] * 6)
  rows = sidebyside.load([str(tmp_path)])
  steps, point, lower, upper, seeds = sidebyside.panel_curves(rows, "eval_success",
                                                              reps=50)["reference"]
  i = list(steps).index(700_000)  # the ramps' 2/3: 0.533, 0.333, 0.133
  assert seeds == 3 and point[i] == pytest.approx((0.533 + 0.333 + 0.133) / 3)
  assert lower[i] <= point[i] <= upper[i] and len(steps) == 100


# -- the study's launcher (results/antpush_reference/run.sh) -------------------------------

LAUNCHER = os.path.join(os.path.dirname(__file__), "..", "results", "antpush_reference",
                        "run.sh")


def _launcher(tmp_path):
  """A checkout holding the launcher and committed rows of ours (to env step 20K, a row per
  seed), and a worktree beside it, as the launcher finds them."""
  import shutil
  import subprocess
  main, tree = tmp_path / "main", tmp_path / "study2"
  folder = main / "results" / "antpush_reference"
  (folder / "ours").mkdir(parents=True)
  shutil.copy(LAUNCHER, folder / "run.sh")
  rows = ["task,method,seed,env_step,eval_success"] + [
      f"AntPush,ours,{k},{x},0.0" for x in (10_000, 20_000) for k in (0, 1)]
  (folder / "ours" / "metrics.csv").write_text("\n".join(rows) + "\n")
  git = lambda *a: subprocess.run(["git", "-C", str(main), *a], check=True, capture_output=True)
  git("init", "-q")
  git("-c", "user.name=t", "-c", "user.email=t@t", "add", ".")
  git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "rows")
  (tree / "results" / "antpush_reference" / "ours").mkdir(parents=True)

  def run(*args):
    env = {**os.environ, "STUDY_TREE": str(tree), "GIT_AUTHOR_NAME": "t",
           "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    return subprocess.run(["bash", str(folder / "run.sh"), *args], env=env, text=True,
                          capture_output=True)
  running = tree / "results" / "antpush_reference" / "ours" / "metrics.csv"
  return rows, folder / "ours" / "metrics.csv", running, run


def test_the_launcher_commits_rows_that_extend_the_committed_ones_and_refuses_others(tmp_path):
  rows, committed, running, run = _launcher(tmp_path)
  # A run's rows that repeat the committed ones and go on: copied and committed.
  longer = rows + ["AntPush,ours,0,30000,0.0", "AntPush,ours,1,30000,0.0"]
  running.write_text("\n".join(longer) + "\nAntPush,ours,0,40")  # a line being written
  (running.parent / "config.json").write_text('{"run": 1}')
  (running.parent.parent / "logs").mkdir()
  (running.parent.parent / "logs" / "ours.log").write_text("ours step 30000/1100000\n")
  out = run("sync", "to 30K")
  assert out.returncode == 0, out.stderr
  assert committed.read_text() == "\n".join(longer) + "\n"
  assert (committed.parent / "config.json").read_text() == '{"run": 1}'
  assert (committed.parent / "run.log").read_text() == "ours step 30000/1100000\n"
  assert "rows to ours env step 30000 (to 30K)" in out.stdout
  assert "rows to env step 30000 here, 30000 committed" in run("status").stdout
  # Another run of the same seeds (another machine): its rows differ, nothing is copied.
  other = longer[:3] + ["AntPush,ours,0,20000,0.5"] + longer[4:] + ["AntPush,ours,0,40000,0.0"]
  running.write_text("\n".join(other) + "\n")
  (running.parent / "config.json").write_text('{"run": 2}')
  out = run("sync", "another run")
  assert out.returncode == 1 and "differ from the committed ones" in out.stderr
  assert committed.read_text() == "\n".join(longer) + "\n"
  assert (committed.parent / "config.json").read_text() == '{"run": 1}'
  # Fewer rows than committed, the same ones: nothing to do.
  running.write_text("\n".join(rows) + "\n")
  (running.parent / "config.json").write_text('{"run": 1}')
  out = run("sync", "behind")
  assert out.returncode == 0 and "no new rows" in out.stdout


def test_the_launcher_joins_a_restarted_runs_log_to_the_committed_one(tmp_path):
  """A run started again from step 0 on a new machine whose rows repeat the committed ones (the
  same CPU model) has a log of its own: the committed log stays, the new one goes on after it,
  in the lane's log too, so that later syncs extend it."""
  rows, committed, running, run = _launcher(tmp_path)
  logs = running.parent.parent / "logs"
  logs.mkdir()
  (logs / "ours.log").write_text("first start\nours step 20000/1100000\n")
  running.write_text("\n".join(rows) + "\n")
  assert run("sync").returncode == 0  # the first start's log committed
  (logs / "ours.log").write_text("second start\n")  # the worktree lost, the run started again
  running.write_text("\n".join(rows[:3]) + "\n")
  out = run("sync")
  assert out.returncode == 0, out.stderr
  joined = (committed.parent / "run.log").read_text().splitlines()
  assert joined[:2] == ["first start", "ours step 20000/1100000"]
  assert joined[2].startswith("# run.sh sync, ") and "the run started again" in joined[2]
  assert joined[3:] == ["second start"]
  assert (logs / "ours.log").read_text().splitlines() == joined
  with open(logs / "ours.log", "a") as f:  # the run goes on writing to the lane's log
    f.write("ours step 10000/1100000\n")
  assert run("sync").returncode == 0
  assert (committed.parent / "run.log").read_text().splitlines() == joined + [
      "ours step 10000/1100000"]


def test_the_launcher_takes_a_resumed_reference_run_whose_rows_differ_only_in_times(tmp_path):
  """A reference run resumed from its checkpoint at t writes its evaluation row of t again,
  with its own times (``reference.logs.TIMING``); the rest of the row is the same. Its rows are
  taken; a row differing in anything else is not."""
  _, _, _, run = _launcher(tmp_path)
  seed = "results/antpush_reference/reference/seed1/evaluations.csv"
  committed, running = tmp_path / "main" / seed, tmp_path / "study2" / seed
  header = "t,step,success_rate,eval_s,train_steps_per_s,wall_s"
  rows = [header, "10000,0,0.0,21.1,78.2,100.0", "20000,10000,0.0,20.5,79.0,300.5"]
  committed.parent.mkdir(parents=True)
  committed.write_bytes("\r\n".join(rows).encode() + b"\r\n")  # as the csv module writes
  again = rows[:2] + ["20000,10000,0.0,22.9,,310.0", "30000,20000,0.02,19.8,80.1,500.0"]
  running.parent.mkdir(parents=True)
  running.write_bytes("\r\n".join(again).encode() + b"\r\n")
  out = run("sync")
  assert out.returncode == 0, out.stderr
  assert committed.read_bytes() == running.read_bytes()  # the run's own times, as it wrote them
  other = again[:2] + ["20000,10000,0.02,22.9,,310.0"] + again[3:] + ["40000,30000,0.0,1,2,3"]
  running.write_bytes("\r\n".join(other).encode() + b"\r\n")
  out = run("sync")
  assert out.returncode == 1 and "differ from the committed ones" in out.stderr
  assert committed.read_bytes() == "\r\n".join(again).encode() + b"\r\n"


def test_the_launcher_takes_a_run_whose_last_rows_are_committed_as_done(tmp_path):
  rows, committed, _, run = _launcher(tmp_path)
  ours_line = lambda: next(line for line in run("status").stdout.splitlines()
                           if line.startswith("ours:"))
  assert ours_line() == "ours: rows to env step - here, 20000 committed"
  committed.write_text("\n".join(rows + ["AntPush,ours,0,1100000,0.1"]) + "\n")
  assert ours_line() == "ours: rows to env step - here, 1100000 committed; done"
  assert run("ours").stdout.strip() == "ours: done"
