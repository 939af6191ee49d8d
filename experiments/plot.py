"""Draw the paper's figures from run folders: ``python -m experiments.plot DIR [DIR ...]``.

Per task found in the folders' ``metrics.csv`` files:

- ``<task>_success``: S_E (evaluation success rate of Middle TD3 + Low TD3) and the evaluation
  return against env steps, one line per method: the mean over seeds with a band of one
  standard deviation (the paper's success-rate and reward figures);
- ``<task>_modes``: for every method, the cumulative Middle decisions made in each mode (TD3 =
  exploitation, PPO and RANDOM = exploration; one decision per c = 10 env steps, the unit of
  the paper's mode counts) against env steps (runs from before these columns: env steps);
- ``<task>_ablation``: S_E of ours and its ablations, where the folders hold any of them.

Each is written as PNG and PDF into ``--out`` (default: ``DIR/figures`` of the first folder);
``--table`` also prints final and best S_E (mean +- std over seeds) and the Middle decisions
per mode after the starting mode (the paper's unit; env steps in brackets).
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
from collections import defaultdict

import numpy as np

MODES = ("TD3", "PPO", "RANDOM")
LABELS = {"ours": "Ours", "hiro": "HIRO", "ref-uniform": "Ref:Uniform", "ref-ppo": "Ref:PPO",
          "ours-no-reward-mod": "Ours w/o reward mod.", "ours-no-loss-mod": "Ours w/o loss mod.",
          "ours-no-mods": "Ours w/o both"}
ABLATIONS = ("ours", "ours-no-reward-mod", "ours-no-loss-mod", "ours-no-mods")
MODE_COLORS = {"TD3": "tab:blue", "PPO": "tab:orange", "RANDOM": "tab:green"}


REQUIRED = ("task", "method", "seed", "env_step", "eval_success", "eval_return",
            *(f"cum_steps_{m}" for m in MODES))


def load(dirs) -> list[dict]:
  """Every folder's rows, all checked before anything is drawn; raises ValueError naming the
  file and line. A half-written last line (a run killed mid-row) is skipped, as resume does."""
  rows = []
  for d in dirs:
    path = os.path.join(d, "metrics.csv")
    if not os.path.isfile(path):
      raise ValueError(f"{path} not found (is {d} a run folder?)")
    rows.extend(_read(path))
  return rows


def _read(path: str) -> list[dict]:
  try:
    with open(path, newline="") as f:
      text = f.read()
  except (OSError, UnicodeDecodeError) as e:
    raise ValueError(f"{path}: cannot be read ({e})") from None
  lines = text.splitlines()
  header = next(csv.reader(lines[:1]), [])
  missing = [c for c in REQUIRED if c not in header]
  if missing:
    raise ValueError(f"{path}: the header is not a metrics file's (no {', '.join(missing)})")
  parsed = list(csv.reader(lines[1:]))
  if parsed and (not text.endswith("\n") or not _row_ok(header, parsed[-1])):
    parsed = parsed[:-1]  # half-written
  for i, values in enumerate(parsed):
    if not _row_ok(header, values):
      raise ValueError(f"{path}: line {i + 2} is malformed: {lines[i + 1][:60]!r}")
  return [dict(zip(header, values)) for values in parsed]


def _row_ok(header, values) -> bool:
  if len(values) != len(header):
    return False
  row = dict(zip(header, values))
  try:
    int(row["env_step"]), int(row["seed"])
    for c in REQUIRED[4:]:
      if row[c] != "":
        float(row[c])
  except ValueError:
    return False
  return True


def curves(rows, task, method, column):
  """(steps, mean, std) over seeds of ``column``; steps where every seed has a value."""
  by_step = defaultdict(dict)
  for r in rows:
    if r["task"] == task and r["method"] == method and r.get(column, "") != "":
      by_step[int(r["env_step"])][r["seed"]] = float(r[column])
  n_seeds = max((len(v) for v in by_step.values()), default=0)
  steps = sorted(s for s, v in by_step.items() if len(v) == n_seeds)
  values = np.array([[by_step[s][k] for k in sorted(by_step[s])] for s in steps])
  if not steps:
    return np.zeros(0), np.zeros(0), np.zeros(0), 0
  return np.array(steps), values.mean(1), values.std(1), n_seeds


def _last(rows, task, method, column):
  """The mean over seeds of ``column`` at the last logged step (None: a run without it)."""
  if not any(column in r and r[column] != "" for r in rows):
    return None
  _, mean, _, n = curves(rows, task, method, column)
  return float(mean[-1]) if n else None


def summary(rows) -> list[dict]:
  """Per task and method: final and best mean S_E (with the std across seeds), the mean
  cumulative env steps per mode at the last logged step, and per mode the mean Middle
  decisions and env steps after the starting mode (None for runs without those columns)."""
  out = []
  for task in sorted({r["task"] for r in rows}):
    for m in LABELS:
      steps, mean, std, n = curves(rows, task, m, "eval_success")
      if not n:
        continue
      best = int(np.argmax(mean))
      modes = {mode: curves(rows, task, m, f"cum_steps_{mode}")[1] for mode in MODES}
      after = {mode: _last(rows, task, m, f"cum_decisions_after_start_{mode}")
               for mode in MODES}
      after_steps = {mode: _last(rows, task, m, f"cum_steps_after_start_{mode}")
                     for mode in MODES}
      out.append({"task": task, "method": m, "seeds": n, "env_steps": int(steps[-1]),
                  "final_s_e": float(mean[-1]), "final_s_e_std": float(std[-1]),
                  "best_s_e": float(mean[best]), "best_s_e_std": float(std[best]),
                  "best_at": int(steps[best]),
                  **{f"steps_{mode}": float(v[-1]) if len(v) else 0.0
                     for mode, v in modes.items()},
                  **{f"decisions_after_start_{mode}": v for mode, v in after.items()},
                  **{f"steps_after_start_{mode}": v for mode, v in after_steps.items()}})
  return out


def _modes_cell(r) -> str:
  """Per-seed mean Middle decisions per mode after the starting mode (env steps in brackets);
  runs from before the decision columns show env steps after warm-up."""
  if r.get("decisions_after_start_TD3") is None:
    return " / ".join(f"{r[f'steps_{m}']:.0f}" for m in MODES) + " env steps"
  return " / ".join(f"{r[f'decisions_after_start_{m}']:.0f} ({r[f'steps_after_start_{m}']:.0f})"
                    for m in MODES)


def markdown_table(summary_rows) -> str:
  lines = ["| task | method | seeds | env steps | final S_E | best S_E (at) | TD3 / PPO / RANDOM "
           "Middle decisions after the starting mode, per seed (env steps) |",
           "|---|---|---|---|---|---|---|"]
  for r in summary_rows:
    lines.append(
        f"| {r['task']} | {LABELS[r['method']]} | {r['seeds']} | {r['env_steps']} | "
        f"{r['final_s_e']:.2f} +- {r['final_s_e_std']:.2f} | {r['best_s_e']:.2f} +- "
        f"{r['best_s_e_std']:.2f} ({r['best_at']}) | {_modes_cell(r)} |")
  return "\n".join(lines)


def _band(ax, steps, mean, std, label, color=None):
  line, = ax.plot(steps, mean, label=label, color=color, lw=1.6)
  ax.fill_between(steps, mean - std, mean + std, color=line.get_color(), alpha=0.2, lw=0)


def _finish(fig, out, name):
  fig.tight_layout()
  paths = []
  for ext in ("png", "pdf"):
    path = os.path.join(out, f"{name}.{ext}")
    fig.savefig(path, dpi=150)
    paths.append(path)
  return paths


def plot(dirs, out=None) -> list[str]:
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt

  rows = load(dirs)
  out = out or os.path.join(dirs[0], "figures")
  os.makedirs(out, exist_ok=True)
  written = []
  for task in sorted({r["task"] for r in rows}):
    present = [m for m in LABELS if any(r["task"] == task and r["method"] == m for r in rows)]

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for m in present:
      steps, mean, std, n = curves(rows, task, m, "eval_success")
      _band(ax1, steps, mean, std, f"{LABELS[m]} ({n} seeds)")
      steps, mean, std, n = curves(rows, task, m, "eval_return")
      _band(ax2, steps, mean, std, LABELS[m])
    ax1.set(title=f"{task}: success rate", xlabel="env steps",
            ylabel="S_E (Middle TD3 + Low TD3)", ylim=(-0.05, 1.05))
    ax2.set(title=f"{task}: evaluation return", xlabel="env steps", ylabel="return per episode")
    ax1.legend(fontsize=8)
    for ax in (ax1, ax2):
      ax.grid(alpha=0.3)
    written += _finish(fig, out, f"{task.lower()}_success")
    plt.close(fig)

    fig, axes = plt.subplots(1, len(present), figsize=(max(3.6 * len(present), 6.5), 3.4),
                             sharey=True, squeeze=False)
    unit = "decisions" if all(r.get("cum_decisions_TD3", "") != "" for r in rows
                              if r["task"] == task) else "steps"
    for ax, m in zip(axes[0], present):
      for mode in MODES:
        steps, mean, std, _ = curves(rows, task, m, f"cum_{unit}_{mode}")
        _band(ax, steps, mean, std, mode, MODE_COLORS[mode])
      ax.set(title=LABELS[m], xlabel="env steps")
      ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("Middle decisions in the mode (cumulative)" if unit == "decisions"
                          else "env steps run in the mode (cumulative)")
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"{task}: exploitation (TD3) and exploration (PPO, RANDOM)")
    written += _finish(fig, out, f"{task.lower()}_modes")
    plt.close(fig)

    ablations = [m for m in ABLATIONS if m in present]
    if len(ablations) > 1:
      fig, ax = plt.subplots(figsize=(5.5, 4))
      for m in ablations:
        steps, mean, std, n = curves(rows, task, m, "eval_success")
        _band(ax, steps, mean, std, f"{LABELS[m]} ({n} seeds)")
      ax.set(title=f"{task}: ablations", xlabel="env steps", ylabel="S_E", ylim=(-0.05, 1.05))
      ax.legend(fontsize=8)
      ax.grid(alpha=0.3)
      written += _finish(fig, out, f"{task.lower()}_ablation")
      plt.close(fig)
  return written


def main(argv=None) -> int:
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("dirs", nargs="+", help="run folders (each with a metrics.csv)")
  p.add_argument("--out", default=None, help="figure folder (default: DIR/figures)")
  p.add_argument("--table", action="store_true",
                 help="also print a Markdown table of final / best S_E and mode counts")
  args = p.parse_args(argv)
  try:
    written = plot(args.dirs, args.out)
    rows = load(args.dirs) if args.table else None
  except ValueError as e:
    p.exit(2, f"{p.prog}: error: {e}\n")
  except OSError as e:  # the figure folder
    p.exit(2, f"{p.prog}: error: {e.filename}: {e.strerror}\n")
  for path in written:
    print(path)
  if rows is not None:
    print(markdown_table(summary(rows)))
  return 0


if __name__ == "__main__":
  sys.exit(main())
