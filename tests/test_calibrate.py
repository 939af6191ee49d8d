"""The study's budget rule (experiments/calibrate.py) on hand-made calibration rows."""

import numpy as np

from experiments import calibrate


def _rows(method, success_of_step, last, seeds=4, task="PointFall"):
  """One row per 2K env steps up to ``last``; ``success_of_step(step, seed)`` is S_E."""
  return [{"task": task, "method": method, "seed": str(k), "env_step": str(t),
           "eval_success": str(success_of_step(t, k))}
          for t in range(2000, last + 1, 2000) for k in range(seeds)]


def test_window_mean_averages_the_five_evaluations_ending_at_the_step():
  steps = np.arange(2000, 20001, 2000)
  values = np.tile(np.arange(10, dtype=float), (2, 1))  # 0..9 at 2K..20K
  assert calibrate.window_mean(steps, values, 10_000) == np.mean([0, 1, 2, 3, 4])
  assert calibrate.window_mean(steps, values, 11_000) == np.mean([0, 1, 2, 3, 4])
  assert calibrate.window_mean(steps, values, 8000) is None  # four evaluations only
  assert calibrate.window_mean(steps, values, 22_000) is None  # not reached


def test_one_seed_of_four_at_full_success_decides_100k():
  # 0.25 >= 0 + 0.2: one method is enough, even while the other is short of 100K.
  rows = _rows("ours", lambda t, k: float(k == 3 and t >= 60_000), 100_000)
  rows += _rows("hiro", lambda t, k: 0.0, 90_000)
  head, lines = calibrate.calibrate(rows, "PointFall")
  assert "B = 100K" in head and "runs at 100K" in head, head
  assert any(line.startswith("| ours | 4 | 100000 | 0.250 |") for line in lines), lines


def test_the_bar_is_strict_about_the_window_and_the_floor():
  # At 100K ours' window holds one good evaluation of one seed: 1/20 < 0.2; at 200K it holds
  # five: 0.25 >= 0.2. On PointPush (floor 0.004) 0.2 is short of the bar.
  late = lambda t, k: float(k == 0 and t >= 100_000)
  rows = _rows("ours", late, 200_000) + _rows("hiro", lambda t, k: 0.0, 200_000)
  assert "B = 200K" in calibrate.calibrate(rows, "PointFall")[0]
  push = _rows("ours", lambda t, k: float(k == 0 and t > 100_000) * 0.8, 200_000,
               task="PointPush")
  head = calibrate.calibrate(push, "PointPush")[0]
  assert "undecided: not every method has reached 500K" in head, head


def test_large_budgets_are_capped_and_nothing_learned_runs_at_200k():
  late = lambda t, k: float(t >= 600_000)
  rows = _rows("ours", late, 1_000_000, seeds=1) + _rows("hiro", lambda t, k: 0, 1_000_000, 1)
  assert "B = 1000K, capped at 500K; the comparison runs at 500K" in \
      calibrate.calibrate(rows, "PointFall")[0]
  nothing = _rows("ours", lambda t, k: 0, 1_000_000, 1) + _rows("hiro", lambda t, k: 0,
                                                                1_000_000, 1)
  assert calibrate.calibrate(nothing, "PointFall")[0].endswith(
      "not learned at CPU scale; the comparison runs at 200K env steps")
