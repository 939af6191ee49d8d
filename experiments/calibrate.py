"""The study's budget rule, applied to calibration runs: ``python -m experiments.calibrate DIR``.

The rule (docs/results.md, "The study", step 1, fixed before the comparison): the budget B of a
task is the smallest of 100K, 200K, 500K and 1M env steps at which ours or HIRO reaches a mean
S_E over its seeds, averaged over the five evaluations ending at that step, at least 0.2 above
the random policy's success rate; the comparison runs at min(B, 500K); if neither method reaches
the bar by 1M the task is "not learned at CPU scale" and the comparison runs at 200K.

``DIR`` holds the calibration run folders of one or more tasks (any depth, as ``curves.load``). For
each task it prints, per method and candidate budget, that five-evaluation mean, and the
decision: the budget, "undecided" (the runs have not reached the next candidate yet) or "not
learned at CPU scale".
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from experiments import curves
from nonmono_jax.host import methods

CANDIDATES = (100_000, 200_000, 500_000, 1_000_000)
CAP = 500_000  # the comparison's budget is at most this (compute)
NOT_LEARNED_BUDGET = 200_000  # where the comparison runs on a task nothing learned by 1M
MARGIN = 0.2
WINDOW = 5  # evaluations averaged, ending at the candidate
METHODS = ("ours", "hiro")


def window_mean(steps, values, at: int, window: int = WINDOW) -> float | None:
  """Mean over seeds and over the ``window`` evaluations ending at env step ``at`` (None if
  the runs have not reached ``at`` or hold fewer evaluations)."""
  if not len(steps) or steps[-1] < at:
    return None
  upto = np.flatnonzero(steps <= at)
  if len(upto) < window:
    return None
  return float(values[:, upto[-window:]].mean())


def decide(means: dict[str, dict[int, float | None]], floor: float) -> tuple[str, int | None]:
  """(decision, comparison budget) from each method's window mean at each candidate."""
  for at in CANDIDATES:
    reached = [m.get(at) for m in means.values()]
    if any(v is not None and v >= floor + MARGIN for v in reached):
      budget = min(at, CAP)
      capped = f", capped at {CAP // 1000}K" if budget < at else ""
      return f"B = {at // 1000}K{capped}", budget
    if any(v is None for v in reached):
      return f"undecided: not every method has reached {at // 1000}K", None
  return "not learned at CPU scale", NOT_LEARNED_BUDGET


def calibrate(rows, task: str) -> tuple[str, list[str]]:
  """The decision for ``task`` and a markdown table of the window means behind it."""
  floor = methods.TASKS[task].random_success
  means, lines = {}, []
  header = "| method | seeds | last step | " + " | ".join(f"{c // 1000}K" for c in CANDIDATES)
  lines += [header + " |", "|---" * (3 + len(CANDIDATES)) + "|"]
  for method in METHODS:
    steps, values = curves.per_seed(rows, task, method, "eval_success")
    if not len(steps):
      continue
    means[method] = {c: window_mean(steps, values, c) for c in CANDIDATES}
    cells = ["-" if v is None else f"{v:.3f}" for v in means[method].values()]
    lines.append(f"| {method} | {len(values)} | {steps[-1]} | " + " | ".join(cells) + " |")
  decision, budget = decide(means, floor) if means else ("no calibration runs", None)
  head = f"{task} (random floor {floor}, bar {floor + MARGIN:.3f}): {decision}"
  if budget is not None:
    head += f"; the comparison runs at {budget // 1000}K env steps"
  return head, lines


def main(argv=None) -> int:
  ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                               formatter_class=argparse.RawDescriptionHelpFormatter)
  ap.add_argument("dirs", nargs="+", help="calibration run folders or a tree of them")
  args = ap.parse_args(argv)
  try:
    rows = curves.load(args.dirs)
  except ValueError as e:
    print(f"error: {e}", file=sys.stderr)
    return 2
  for task in sorted({r["task"] for r in rows}):
    head, lines = calibrate(rows, task)
    print("\n".join([head, "", *lines, ""]))
  return 0


if __name__ == "__main__":
  sys.exit(main())
