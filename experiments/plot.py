"""Draw the paper's figures from run folders: ``python -m experiments.plot DIR [DIR ...]``.

Per task found in the folders' ``metrics.csv`` files:

- ``<task>_success``: S_E (the success rate in evaluation, of Middle TD3 + Low TD3) and the
  evaluation return against env steps, one line per method: the mean over seeds with its
  pointwise 95 % stratified-bootstrap interval (the paper's success-rate and reward figures);
- ``<task>_modes``: for every method, the cumulative Middle decisions made in each mode (TD3 =
  exploitation, PPO and RANDOM = exploration; one decision per c = 10 env steps, the unit of
  the paper's mode counts) against env steps (runs from before these columns: env steps), the
  mean over seeds with its 95 % interval, each mode in its own colour and line style (a mode
  never chosen is named in its panel, so a line under another hides nothing);
- ``<task>_iqm``: S_E against env steps as the interquartile mean (IQM) over seeds with
  pointwise 95 % stratified-bootstrap intervals, final S_E as IQM with its interval per
  method, and the probability of improvement P(ours > method) on final S_E with its interval
  (``experiments.stats``, rliable's estimators); an interval that spans nearly all of [0, 1]
  (``UNINFORMATIVE``: too few seeds for it to say anything) is marked so;
- ``<task>_seeds``: S_E of every seed, one panel per method: what the IQM hides when few
  seeds learn (with 6 seeds the IQM trims the best and the worst seed);
- ``<task>_ablation``: S_E of ours and its ablations (IQM with 95 % intervals), where the
  folders hold any of them.

Folders of the Ant Push study of the paper's code beside ours (``results/antpush_reference``:
``experiments.sidebyside.is_study``) draw that study's figure instead, on the paper's axis
(``sidebyside.figures``; ``--table`` prints its readings, as ``experiments.claims`` does).

Each is written as PNG and PDF into ``--out``, or by default into ``DIR/figures`` of the
first folder that holds the task (so ``plot results/point*`` draws each task into its own
results folder), with ``summary.md``: per task and method, final and best S_E per seed as IQM
[95 % CI], P(ours > method) [95 % CI] with the study's reading of it, the Middle decisions per
mode after the starting mode (the paper's unit; env steps in brackets) and the modes' order,
then P(A > B) for the other pairs the study compares (``PAIRS``: Ref:Uniform against Ref:PPO),
then each seed's final S_E and its first evaluation at 0.5 or more (``seeds_table``).
``--table`` also prints them, for every task.

The rows come from ``experiments.curves`` (``plot.load`` is its ``load``); the figures share
``experiments.drawing``'s look with the side-by-side study's.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from experiments import sidebyside, stats
from experiments.curves import AXES, curves, load, per_seed, seed_table
from experiments.drawing import (INTERVAL, MODE_COLORS, MODE_STYLES, STEPS_LABEL,
                                 SUCCESS, band, finish, label, legend_below, seeds_text,
                                 variants)
from nonmono_jax.core.config import MODES  # the Middle's sub-policies (JAX-free)

ABLATIONS = ("ours", "ours-no-reward-mod", "ours-no-loss-mod", "ours-no-mods")
SEEDS_COLUMNS = 4  # panels a row of the per-seed figure
SEEDS_LEGEND = 12  # seeds a panel of it names in a legend, at most
# A 95 % interval at least this wide on [0, 1] tells nothing: with few seeds (4 seeds that end
# at 0 or 1) the bootstrap's resamples reach both ends. Marked in the figures and summary.md.
UNINFORMATIVE = 0.9


def uninformative(estimate) -> bool:
  """Whether an interval estimate (point, lower, upper) on [0, 1] is too wide to say anything."""
  return estimate is not None and float(estimate[2]) - float(estimate[1]) >= UNINFORMATIVE


SUMMARY_NOTE = (
    "Final S_E (at the last evaluation), best S_E (the maximum over evaluations) and early "
    "S_E (at the last evaluation by a quarter of the run, its env step in brackets) per seed, "
    "as the interquartile mean over seeds with a 95% stratified-bootstrap percentile interval "
    "({reps} replicates); P(ours > method): the probability that a seed of ours ends with a "
    "higher final S_E than a seed of the method (ties count 1/2), with its interval "
    "(`experiments/stats.py`). Mode counts: Middle decisions (the paper's unit) after the "
    "starting mode per seed at the last row, IQM over seeds [95% CI] (the IQM of the env steps "
    "in brackets); mode order: the modes by that IQM, neighbours read as the study does (\">\": "
    "the intervals do not overlap; \">>\": also at least 3x; \"~\": they overlap). Reading: "
    "A above B where the interval of P(A > B) lies above 0.5, below it the reverse, else they "
    "cannot be told apart.\n\n")


def _at_end(rows, task, method, column, reps):
  """(IQM, lower, upper) over seeds of ``column`` at the last step where every seed has a
  value (None: a run without it)."""
  steps, values = per_seed(rows, task, method, column)
  return stats.interval(stats.iqm, values[:, -1], reps=reps) if len(steps) else None


def _early(steps) -> int:
  """The index of the last evaluation at or before a quarter of the run (the first if none):
  where the study reads "HIRO best early"."""
  return max(int(np.searchsorted(steps, steps[-1] / 4, side="right")) - 1, 0)


PAIRS = (("ref-uniform", "ref-ppo"),)  # compared besides ours against each method


def reading(p, a: str, b: str) -> str:
  """The study's reading of P(A > B) (docs/results.md, "The study", 4): A above B if its 95 %
  interval lies above 0.5, B above A if below, else they cannot be told apart."""
  if p is None:
    return "n/a"
  if p[1] > 0.5:
    return f"{label(a)} above {label(b)}"
  if p[2] < 0.5:
    return f"{label(b)} above {label(a)}"
  return "cannot be told apart"


def mode_order(r) -> str:
  """The modes by their IQM of Middle decisions after the starting mode (env steps in all for
  runs without them), each pair of neighbours read as the study does: ">" if the 95 %
  intervals do not overlap, ">>" if the higher IQM is also at least 3x the lower, "~" else."""
  unit = "decisions_after_start" if r["decisions_after_start_TD3"] is not None else "steps"
  cells = sorted(((r[f"{unit}_{m}"], m) for m in MODES), key=lambda c: -float(c[0][0]))
  out = cells[0][1]
  for (hi, _), (lo, name) in zip(cells, cells[1:]):
    apart = float(hi[1]) > float(lo[2])
    much = apart and float(hi[0]) >= 3 * float(lo[0])
    out += (" >> " if much else " > " if apart else " ~ ") + name
  return out


def comparisons(rows, pairs=PAIRS, reps: int = stats.REPS) -> list[dict]:
  """P(A > B) on final S_E with its interval and ``reading``, per task holding both."""
  out = []
  for task in sorted({r["task"] for r in rows}):
    present = variants(rows, task)
    for a, b in pairs:
      if a in present and b in present:
        fa, fb = (per_seed(rows, task, m, "eval_success")[1][:, -1] for m in (a, b))
        p = stats.interval(stats.probability_of_improvement, fa, fb, reps=reps)
        out.append({"task": task, "a": a, "b": b, "p": p, "reading": reading(p, a, b)})
  return out


def summary(rows, reps: int = stats.REPS) -> list[dict]:
  """Per task and method: the final S_E (at the last evaluation), the early S_E (at the last
  evaluation by a quarter of the run, ``early_step``) and best S_E (the maximum over
  evaluations) of every seed as (IQM, lower, upper), a 95 % stratified-bootstrap interval;
  ``p_ours``: P(ours > method) on final S_E, with its interval (None for ours or without it);
  per mode, the same IQM and interval at the last row of the cumulative env steps, and of the
  Middle decisions and env steps after the starting mode (None for runs without them)."""
  out = []
  for task in sorted({r["task"] for r in rows}):
    finals = {}
    for m in variants(rows, task):
      steps, values = per_seed(rows, task, m, "eval_success")
      if not len(steps):
        continue
      finals[m] = values[:, -1]
      counts = {f"{name}_{mode}": _at_end(rows, task, m, f"cum_{name}_{mode}", reps)
                for name in ("steps", "decisions_after_start", "steps_after_start")
                for mode in MODES}
      early = _early(steps)
      out.append({"task": task, "method": m, "seeds": len(values), "env_steps": int(steps[-1]),
                  "early_step": int(steps[early]),
                  "early_s_e": stats.interval(stats.iqm, values[:, early], reps=reps),
                  "final_s_e": stats.interval(stats.iqm, values[:, -1], reps=reps),
                  "best_s_e": stats.interval(stats.iqm, values.max(1), reps=reps),
                  "p_ours": None, **counts})
    for r in out:
      if r["task"] == task and r["method"] != "ours" and "ours" in finals:
        r["p_ours"] = stats.interval(stats.probability_of_improvement, finals["ours"],
                                     finals[r["method"]], reps=reps)
  for r in out:
    r["reading"] = reading(r["p_ours"], "ours", r["method"])
    r["mode_order"] = mode_order(r)
  return out


def _interval_cell(estimate, digits=2) -> str:
  """``point [lower, upper]``; n/a for no estimate."""
  if estimate is None:
    return "n/a"
  point, lower, upper = (f"{float(x):.{digits}f}" for x in estimate)
  return f"{point} [{lower}, {upper}]"


def _mode_cells(r) -> list[str]:
  """Per mode: Middle decisions after the starting mode, IQM [95% CI] over seeds (the IQM of
  the env steps in brackets); runs from before the decision columns: env steps in all."""
  if r["decisions_after_start_TD3"] is None:
    return [_interval_cell(r[f"steps_{m}"], 0) + " env steps" for m in MODES]
  return [f"{_interval_cell(r[f'decisions_after_start_{m}'], 0)} "
          f"({float(r[f'steps_after_start_{m}'][0]):.0f})" for m in MODES]


def markdown_table(summary_rows) -> str:
  lines = ["| task | method | runs | env steps | final S_E, IQM [95% CI] | best S_E, IQM "
           "[95% CI] | early S_E (env step), IQM [95% CI] | P(ours > method), final S_E [95% CI] | "
           "reading | "
           + " | ".join(f"{m} decisions after the starting mode, IQM [95% CI] (env steps)"
                        for m in MODES) + " | mode order |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
  for r in summary_rows:
    lines.append(
        f"| {r['task']} | {label(r['method'])} | {r['seeds']} | {r['env_steps']} | "
        f"{_interval_cell(r['final_s_e'])} | {_interval_cell(r['best_s_e'])} | "
        f"{_interval_cell(r['early_s_e'])} ({r['early_step']}) | "
        f"{_interval_cell(r['p_ours'])} | {r['reading']} | {' | '.join(_mode_cells(r))} | "
        f"{r['mode_order']} |")
  return "\n".join(lines)


def tables(rows, summary_rows=None) -> str:
  """``markdown_table`` of the summary, then ``pairs_table`` where there are pairs, then
  ``seeds_table``: what ``summary.md`` holds after its note and ``--table`` prints."""
  pairs = pairs_table(comparisons(rows))
  summary_rows = summary(rows) if summary_rows is None else summary_rows
  note = too_few_note(summary_rows)
  return (markdown_table(summary_rows) + (f"\n\n{note}" if note else "")
          + (f"\n\n{pairs}" if pairs else "") + f"\n\n{seeds_table(rows)}")


def too_few_note(summary_rows) -> str:
  """A note naming the methods whose final S_E interval spans nearly all of [0, 1]
  (``uninformative``): too few seeds for the interval to say anything (empty if none)."""
  wide = [f"{r['task']} {label(r['method'])} ({seeds_text(r['seeds'])}: "
          f"[{float(r['final_s_e'][1]):.2f}, {float(r['final_s_e'][2]):.2f}])"
          for r in summary_rows if uninformative(r["final_s_e"])]
  if not wide:
    return ""
  return (f"Too few seeds for an interval: the 95% CI of the final S_E spans nearly all of "
          f"[0, 1] for {', '.join(wide)}; it tells nothing about them (more seeds narrow it).")


def seeds_table(rows) -> str:
  """Per task and method: each seed's final S_E (seeds in order), how many end at 0.5 or more,
  how many reached 0.5 at some evaluation but end below it (fell back: the collapses the
  paper's loss modification is meant to avoid), and the env step of each seed's first
  evaluation at 0.5 or more (- for never)."""
  lines = ["| task | method | final S_E per seed | seeds ending >= 0.5 | fell back (reached 0.5, "
           "end below) | first evaluation >= 0.5 per seed (env step) |",
           "|---|---|---|---|---|---|"]
  for task in sorted({r["task"] for r in rows}):
    for m in variants(rows, task):
      steps, values = per_seed(rows, task, m, "eval_success")
      if not len(steps):
        continue
      first = [str(steps[np.argmax(v >= 0.5)]) if (v >= 0.5).any() else "-" for v in values]
      lines.append(f"| {task} | {label(m)} | {', '.join(f'{x:g}' for x in values[:, -1])} | "
                   f"{int((values[:, -1] >= 0.5).sum())} of {len(values)} | "
                   f"{int(((values.max(1) >= 0.5) & (values[:, -1] < 0.5)).sum())} | "
                   f"{', '.join(first)} |")
  return "\n".join(lines)


def pairs_table(comparison_rows) -> str:
  """``comparisons`` as Markdown (empty when there are none)."""
  if not comparison_rows:
    return ""
  lines = ["| task | A | B | P(A > B), final S_E [95% CI] | reading |", "|---|---|---|---|---|"]
  lines += [f"| {c['task']} | {label(c['a'])} | {label(c['b'])} | {_interval_cell(c['p'])} | "
            f"{c['reading']} |" for c in comparison_rows]
  return "\n".join(lines)


def iqm_curves(rows, task, methods) -> dict:
  """Per method with an evaluation: (steps, IQM, lower, upper, seeds) of S_E over seeds, with
  pointwise 95 % stratified-bootstrap intervals."""
  out = {}
  for m in methods:
    steps, values = per_seed(rows, task, m, "eval_success")
    if len(steps):
      out[m] = (steps, *stats.iqm_curve(values), len(values))
  return out


def _iqmband(ax, curve, label, color=None):
  band(ax, curve, f"{label} ({seeds_text(curve[4])})", color, bounds=(0, 1))


def _intervals(ax, labels, estimates, colors):
  """rliable's interval-estimate plot: one horizontal 95 % interval and point per label; an
  interval too wide to say anything (``uninformative``) says so beside it."""
  for i, ((point, lower, upper), color) in enumerate(zip(estimates, colors)):
    ax.plot([lower, upper], [i, i], color=color, lw=6, alpha=0.5, solid_capstyle="butt")
    ax.plot([point], [i], "k|", ms=14)
    if uninformative((point, lower, upper)):
      ax.annotate("too few seeds: the interval tells nothing", (0.5, i), xytext=(0, 9),
                  textcoords="offset points", ha="center", fontsize=7, color="0.3")
  ax.set_yticks(range(len(labels)), labels)
  ax.set_ylim(len(labels) - 0.4, -0.6)
  ax.grid(alpha=0.3, axis="x")


def _iqm_figure(plt, task, curves_, table, out, xlabel=STEPS_LABEL) -> list[str]:
  """IQM of S_E against env steps, final S_E as IQM with its interval and P(ours > method)."""
  baselines = [r for r in table if r["p_ours"] is not None]
  colors = {m: f"C{i}" for i, m in enumerate(curves_)}
  fig, axes = plt.subplots(1, 3 if baselines else 2, figsize=(15 if baselines else 10.5, 4))
  for m, curve in curves_.items():
    _iqmband(axes[0], curve, label(m), colors[m])
  axes[0].set(title=f"{task}: IQM over seeds, {INTERVAL}", xlabel=STEPS_LABEL,
              ylabel=SUCCESS, ylim=(-0.05, 1.05))
  axes[0].grid(alpha=0.3)
  legend_below(fig, axes, 4)
  _intervals(axes[1], [label(r["method"]) for r in table], [r["final_s_e"] for r in table],
             [colors[r["method"]] for r in table])
  axes[1].set(title=f"final {SUCCESS}, IQM, {INTERVAL}", xlim=(-0.05, 1.05))
  if baselines:
    _intervals(axes[2], [f"Ours > {label(r['method'])}" for r in baselines],
               [r["p_ours"] for r in baselines], [colors[r["method"]] for r in baselines])
    axes[2].axvline(0.5, color="gray", ls="--", lw=1)
    axes[2].set(title=f"P(ours > method), final {SUCCESS}, {INTERVAL}", xlim=(-0.05, 1.05))
  return finish(fig, out, f"{task.lower()}_iqm", xlabel)


def _ablation_figure(plt, task, curves_, out, xlabel=STEPS_LABEL) -> list[str]:
  """S_E of ours and its ablations: IQM over seeds with pointwise 95 % intervals."""
  fig, ax = plt.subplots(figsize=(5.5, 4))
  for m, curve in curves_.items():
    _iqmband(ax, curve, label(m))
  ax.set(title=f"{task}: ablations, IQM over seeds, {INTERVAL}", xlabel=STEPS_LABEL,
         ylabel=SUCCESS, ylim=(-0.05, 1.05))
  ax.grid(alpha=0.3)
  legend_below(fig, [ax], 2)
  return finish(fig, out, f"{task.lower()}_ablation", xlabel)


def _seeds_figure(plt, rows, task, methods, out, xlabel=STEPS_LABEL) -> list[str]:
  """S_E of each seed against env steps, one panel per method (the data the IQM summarises),
  at most ``SEEDS_COLUMNS`` panels a row; a legend while there are at most ``SEEDS_LEGEND``
  seeds (more would hide the curves)."""
  cols = min(len(methods), SEEDS_COLUMNS)
  rows_of_panels = -(-len(methods) // cols)
  fig, axes = plt.subplots(rows_of_panels, cols, sharey=True, squeeze=False,
                           figsize=(max(4.2 * cols, 6.5), 4.4 * rows_of_panels))
  for ax in axes.flat[len(methods):]:
    ax.set_visible(False)
  for ax, m in zip(axes.flat, methods):
    steps, seeds, values = seed_table(rows, task, m, "eval_success")
    for k, (seed, seed_values) in enumerate(zip(seeds, values)):
      ax.plot(steps, seed_values, lw=1.1, color=f"C{k % 10}", label=f"seed {seed}")
    ax.set(title=f"{label(m)} ({seeds_text(len(values))})", xlabel=STEPS_LABEL,
           ylim=(-0.05, 1.05))
    ax.grid(alpha=0.3)
    if len(values) <= SEEDS_LEGEND:  # below the panel: a curve at 1.0 stays in sight
      ax.legend(fontsize=7, ncol=min(len(values), 4), loc="upper center",
                bbox_to_anchor=(0.5, -0.2), frameon=False)
  for row in axes:
    row[0].set_ylabel(f"{SUCCESS}, each seed")
  fig.suptitle(f"{task}: {SUCCESS} of every seed")
  return finish(fig, out, f"{task.lower()}_seeds", xlabel)


def figure_folders(dirs, out=None) -> dict:
  """Where each task's figures go: {folder: [task, ...]}; ``out`` for all, or else
  ``DIR/figures`` of the first of ``dirs`` that holds the task."""
  folders: dict = {}
  seen = set()
  for d in dirs:
    tasks = sorted({r["task"] for r in load([d])} - seen)
    seen.update(tasks)
    if tasks:
      folders.setdefault(out or os.path.join(d, "figures"), []).extend(tasks)
  return folders


def plot(dirs, out=None, axis: str | None = None) -> list[str]:
  """Every task's figures and a ``summary.md`` per figure folder (``figure_folders``), on the
  env-step or the paper's axis (``load``); the files written. The Ant Push study of the
  paper's code beside ours (``sidebyside.is_study``): its figure instead, on the paper's axis,
  into ``out`` or ``figures`` of the first folder (``sidebyside.figures``)."""
  if sidebyside.is_study(dirs):
    _paper_axis_only(axis)
    return sidebyside.figures(sidebyside.load(dirs), out or os.path.join(dirs[0], "figures"))
  axis = axis or "env"
  rows = load(dirs, axis)
  written = []
  for folder, tasks in figure_folders(dirs, out).items():
    written += _draw([r for r in rows if r["task"] in tasks], folder, AXES[axis])
  return written


def _success_figure(plt, rows, task, present, out, xlabel=STEPS_LABEL) -> list[str]:
  """The success rate and the evaluation return of each method: means over seeds with their
  95 % intervals (the success rate's clipped to [0, 1])."""
  fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
  for i, m in enumerate(present):
    curve = curves(rows, task, m, "eval_success")
    band(ax1, curve, f"{label(m)} ({seeds_text(curve[4])})", f"C{i}", bounds=(0, 1))
    band(ax2, curves(rows, task, m, "eval_return"), label(m), f"C{i}")
  ax1.set(title=f"{task}: {SUCCESS}, mean over seeds, {INTERVAL}", xlabel=STEPS_LABEL,
          ylabel=f"{SUCCESS} (evaluation)", ylim=(-0.05, 1.05))
  ax2.set(title=f"{task}: evaluation return, mean, {INTERVAL}", xlabel=STEPS_LABEL,
          ylabel="return per episode")
  for ax in (ax1, ax2):
    ax.grid(alpha=0.3)
  legend_below(fig, [ax1], 4)
  return finish(fig, out, f"{task.lower()}_success", xlabel)


def _modes_figure(plt, rows, task, present, out, xlabel=STEPS_LABEL) -> list[str]:
  """The Middle decisions (or env steps) in each mode, cumulative, per method: means over
  seeds with their 95 % intervals, each mode in its colour and line style; the modes a method
  never chose are named in its panel (their lines lie on 0, one over another)."""
  fig, axes = plt.subplots(1, len(present), figsize=(max(3.6 * len(present), 6.5), 3.9),
                           sharey=True, squeeze=False)
  unit = "decisions" if all(r.get("cum_decisions_TD3", "") != "" for r in rows
                            if r["task"] == task) else "steps"
  for ax, m in zip(axes[0], present):
    never = []
    for mode in MODES:
      curve = curves(rows, task, m, f"cum_{unit}_{mode}")
      band(ax, curve, mode, MODE_COLORS[mode], bounds=(0, np.inf), ls=MODE_STYLES[mode])
      if len(curve[1]) and not np.any(curve[1]):
        never.append(mode)
    if never:
      ax.text(0.03, 0.97, f"never chosen: {', '.join(never)}", transform=ax.transAxes,
              va="top", fontsize=7, color="0.3")
    ax.set(title=label(m), xlabel=STEPS_LABEL)
    ax.grid(alpha=0.3)
  axes[0][0].set_ylabel("Middle decisions in the mode (cumulative)" if unit == "decisions"
                        else "env steps run in the mode (cumulative)")
  legend_below(fig, [axes[0][0]], 3)
  fig.suptitle(f"{task}: the modes chosen, mean over seeds, {INTERVAL}")
  return finish(fig, out, f"{task.lower()}_modes", xlabel)


def _draw(rows, out, xlabel=STEPS_LABEL) -> list[str]:
  """The figures of every task in ``rows`` and their ``summary.md`` into folder ``out``."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt

  table = summary(rows)
  os.makedirs(out, exist_ok=True)
  written = []
  for task in sorted({r["task"] for r in rows}):
    present = variants(rows, task)

    written += _success_figure(plt, rows, task, present, out, xlabel)
    written += _modes_figure(plt, rows, task, present, out, xlabel)

    iqm = iqm_curves(rows, task, present)
    written += _iqm_figure(plt, task, iqm, [r for r in table if r["task"] == task], out,
                           xlabel)
    if iqm:  # the methods with an evaluation
      written += _seeds_figure(plt, rows, task, list(iqm), out, xlabel)
    ablations = [m for m in ABLATIONS if m in iqm]
    if len(ablations) > 1:
      written += _ablation_figure(plt, task, {m: iqm[m] for m in ablations}, out, xlabel)
  path = os.path.join(out, "summary.md")
  with open(path, "w") as f:
    f.write(SUMMARY_NOTE.format(reps=stats.REPS) + tables(rows, table) + "\n")
  written.append(path)
  return written


def main(argv=None) -> int:
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("dirs", nargs="+", help="run folders (each with a metrics.csv), or the Ant "
                 "Push study of the paper's code beside ours (results/antpush_reference)")
  p.add_argument("--out", default=None,
                 help="figure folder for every task (default: DIR/figures of the first DIR "
                      "that holds the task)")
  p.add_argument("--table", action="store_true",
                 help="also print a Markdown table of final / best S_E and mode counts")
  p.add_argument("--axis", choices=tuple(AXES), default=None,
                 help="x-axis: env steps (default) or the paper's, env steps after the "
                      "warm-up (its code logs at t - start_timestep); the Ant Push study of "
                      "the paper's code is drawn on the paper's axis only")
  args = p.parse_args(argv)
  try:
    written = plot(args.dirs, args.out, args.axis)
    table = _table_text(args.dirs, args.axis) if args.table else None
  except ValueError as e:
    p.exit(2, f"{p.prog}: error: {e}\n")
  except OSError as e:  # the figure folder
    p.exit(2, f"{p.prog}: error: {e.filename}: {e.strerror}\n")
  for path in written:
    print(path)
  if table is not None:
    print(table)
  return 0


def _table_text(dirs, axis: str | None) -> str:
  """What ``--table`` prints: ``tables`` of the folders' rows, or the study's readings."""
  if sidebyside.is_study(dirs):
    _paper_axis_only(axis)
    return sidebyside.markdown(sidebyside.readings(sidebyside.load(dirs))).rstrip("\n")
  return tables(load(dirs, axis or "env"))


def _paper_axis_only(axis: str | None) -> None:
  """The study of the paper's code beside ours has one axis, the paper's."""
  if axis not in (None, "paper"):
    raise ValueError(f"the study of the paper's code beside ours is drawn on the paper's axis "
                     f"(env steps after the warm-up) only, not --axis {axis}")


if __name__ == "__main__":
  sys.exit(main())

