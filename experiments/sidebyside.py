"""The decisive Ant Push study's readings: the paper's own code and ours, side by side
(``results/antpush_reference/README.md`` states the protocol; written and tested on made-up
rows before any of its results existed).

    python -m experiments.claims results/antpush_reference            # picks this study
    python -m experiments.claims results/antpush_reference --reps exact

Everything is read on the paper's axis, env steps after the 100K warm-up (``x``; the paper's
code logs at t - start_timestep, so its "1M" is env step 1.1M). The reference runs are the
harness's folders (``reference/``: ``evaluations.csv``, ``windows.csv``, ``config.json``),
turned into rows of the long form of ``metrics.csv`` (``reference_rows``); ours and HIRO are
run folders (``experiments.curves.load(..., axis="paper")``).

The readings (R1-R6 of the protocol):

R1. the paper's code reproduces its headline: its S_E at x = 1M, the mean over seeds, against
    0.6;
R2. ours (the code's choices) at x = 1M, the IQM over seeds, against 0.6 (the first study's
    claim 1, read on the paper's axis);
R3. ours learns like the reference: each seed's late S_E (the mean of its evaluations with
    0.9M <= x <= 1M), ours' mean minus the reference's, against the equivalence margin 0.2;
R4. the final distance to the target, late, the same difference (described);
R5. the Low: its mean reward per env step, and its mean progress per segment towards its
    subgoal (||g_0|| - ||g_c||), over the 50K env steps up to x = 200K, 500K, 1M (described;
    both sides log them);
R6. the modes: Middle decisions per mode from the end of warm-up to x = 1M (described: ours
    has the text's 250K starting mode, the code none).

Intervals are 95 % stratified-bootstrap percentile intervals (``experiments.stats``), 2000
replicates drawn with seed 0 unless ``--reps`` says otherwise; with 3 reference seeds every
resample is cheap, and ``--reps exact`` gives them.

The figure (``figures``), the same rows on one axis:

    python -m experiments.plot results/antpush_reference      # into DIR/figures, or --out

``antpush_sidebyside`` (PNG and PDF): the paper's code, ours and HIRO (where its rows exist),
each the mean over seeds with its pointwise 95 % band, on the paper's axis to 1M: (a) S_E at
each evaluation, each seed thin, the paper's headline 0.6 dashed; (b) the final distance to
the target at each evaluation; (c) the Low's reward per env step; (d) the Low's progress per
segment (where logged). A run still going is drawn as far as it got.
"""

from __future__ import annotations

import csv
import json
import os
from collections import defaultdict

import numpy as np

from experiments import curves, drawing, stats
from nonmono_jax.core.config import MODES  # the Middle's sub-policies (JAX-free)

TASK = "AntPush"
REFERENCE = "reference"  # the method name of the paper's code's rows
AT = 1_000_000  # the paper's 1M (x): R1, R2, R6
LATE = (900_000, 1_000_000)  # R3, R4: every evaluation with LATE[0] <= x <= LATE[1]
MARGIN = 0.2  # R3: "like the reference" if the difference's interval lies within +-MARGIN
SEEDS = {REFERENCE: 3, "ours": 6}  # the protocol's seeds: a reading needs every one of them
TOLERANCE = 1e-9  # an interval's end read against a level or the margin: a rounding is not a side
PASS = 0.6  # the paper's headline: S_E above 0.6 at its 1M
LOW_AT = (200_000, 500_000, 1_000_000)  # R5, each over the LOW_SPAN env steps up to it
LOW_SPAN = 50_000
LOW_COLUMNS = {"low_reward": "reward per env step",
               "low_subgoal_progress": "progress per segment, ||g_0|| - ||g_c||"}
# The reference's mode counts (the code's names: on-policy is the Middle PPO, off-policy TD3)
REFERENCE_COUNTS = {"TD3": "off_policy_count", "PPO": "on_policy_count",
                    "RANDOM": "random_policy_count"}


def _csv(path: str, numbers=()) -> list[dict]:
  """The rows of a harness CSV; a half-written last line (a run killed mid-row) is left out,
  as the harness's resume cuts it; any other row short of cells, or whose ``numbers`` columns
  are not finite numbers, is a ValueError naming its line."""
  try:
    with open(path, newline="") as f:
      rows = list(csv.DictReader(f))
  except OSError as e:
    raise ValueError(f"{path}: cannot be read ({e.strerror or e})") from None
  if rows and not _row_ok(rows[-1], numbers):
    rows = rows[:-1]
  for i, r in enumerate(rows):
    if not _row_ok(r, numbers):
      raise ValueError(f"{path}: line {i + 2} is malformed or not finite: {r}")
  return rows


def _row_ok(row: dict, numbers) -> bool:
  if None in row or None in row.values():  # too many cells, or too few
    return False
  try:
    return all(np.isfinite(float(row[c])) for c in numbers)
  except (KeyError, ValueError):
    return False


def reference_folders(d: str) -> list[str]:
  """The reference harness's run folders at or below ``d`` (each with evaluations.csv)."""
  found = sorted(root for root, _, files in os.walk(d) if "evaluations.csv" in files)
  return found


def reference_seed(folder: str) -> str:
  """The seed of a harness run folder, from its ``config.json``."""
  try:
    with open(os.path.join(folder, "config.json")) as f:
      return str(json.load(f)["seed"])
  except (OSError, ValueError, KeyError) as e:
    raise ValueError(f"{folder}/config.json: the run's seed cannot be read ({e})") from None


def reference_rows(folder: str, seed: str | None = None) -> list[dict]:
  """One harness run folder as rows of the long form of ``metrics.csv`` on the paper's axis:
  an evaluation row per evaluation (``eval_success`` the code's 'success rate',
  ``eval_success_ppo`` its 'higher success rate', ``eval_distance``) and a row per window of
  the Low's reward (``low_reward``) and the mode counts since warm-up (``cum_decisions_*``).
  ``env_step`` is the code's logged step, t - start_timestep. ``seed``: the folder's, if
  read already (``reference_seed``)."""
  base = {"task": TASK, "method": REFERENCE, "seed": seed or reference_seed(folder)}
  rows = []
  for r in _csv(os.path.join(folder, "evaluations.csv"),
                ("step", "success_rate", "final_distance")):
    rows.append({**base, "env_step": r["step"], "eval_success": r["success_rate"],
                 "eval_success_ppo": r.get("higher_success_rate", ""),
                 "eval_distance": r["final_distance"]})
  for r in _csv(os.path.join(folder, "windows.csv"),
                ("step", *REFERENCE_COUNTS.values())):
    if int(r["step"]) > 0:
      rows.append({**base, "env_step": r["step"], "eval_success": "",
                   "low_reward": r["low_intrinsic_reward_mean"],
                   "low_subgoal_progress": r.get("subgoal_progress", ""),
                   **{f"cum_decisions_{m}": r[c] for m, c in REFERENCE_COUNTS.items()}})
  return rows


def load(dirs) -> list[dict]:
  """The reference's rows and our run folders' rows (paper's axis) under ``dirs``; raises
  ValueError naming a file that is not what it should be."""
  rows, seen = [], {}
  for d in dirs:
    for folder in reference_folders(d):
      seed = reference_seed(folder)
      if seed in seen:
        raise ValueError(f"{seen[seed]} and {folder} are both the reference's seed {seed}: "
                         f"keep one (a copy elsewhere than under the study's folder)")
      seen[seed] = folder
      rows += reference_rows(folder, seed)
    ours = [root for root, _, files in os.walk(d) if "metrics.csv" in files]
    if ours:
      rows += curves.load(ours, axis="paper")
  if not rows:
    raise ValueError(f"no reference runs and no run folders in {', '.join(dirs)}")
  return rows


def seeds_of(rows, method) -> list[str]:
  """Every seed of ``method`` with any row, in numeric order."""
  return sorted({r["seed"] for r in rows if r["method"] == method}, key=curves.seed_order)


def by_seed(rows, method, column, lo, hi) -> tuple[list[str], np.ndarray, str | None]:
  """(seeds, each seed's mean of ``column`` over its values with lo <= x <= hi, why not). A
  reading is made only on the protocol's seeds (``SEEDS``), each with a value at every x of the
  window where any seed of the method has one, ``hi`` among them; else ``why not`` says what
  is missing (and the readings use none of the values)."""
  values = defaultdict(dict)  # seed -> {x: value}
  for r in rows:
    x = int(r["env_step"])
    if r["method"] == method and r.get(column, "") != "" and lo <= x <= hi:
      if values[r["seed"]].setdefault(x, float(r[column])) != float(r[column]):
        raise ValueError(f"{method} seed {r['seed']} has two values of {column} at x = {x}")
  seeds = seeds_of(rows, method)
  xs = set().union(*values.values()) if values else set()
  short = [s for s in seeds if set(values.get(s, {})) != xs]
  why = (f"{len(seeds)} of the protocol's {SEEDS[method]} seeds" if len(seeds) != SEEDS[method]
         else f"x = {hi} not reached" if hi not in xs
         else f"seed {', '.join(short)} without every value of {lo}-{hi}" if short else None)
  have = [s for s in seeds if values.get(s)]
  return have, np.array([np.mean(list(values[s].values())) for s in have]), why


def mean(x):
  return np.asarray(x).mean(axis=(0, 1))


def difference(x, y):
  return mean(x) - mean(y)


def versus_level(iv, level: float) -> str:
  _, lo, hi = iv
  return ("holds" if lo >= level - TOLERANCE else "does not hold" if hi < level - TOLERANCE
          else "cannot be told apart")


def equivalence(iv, margin: float = MARGIN) -> str:
  """R3's reading of the difference ours - reference: within the margin, below or above (the
  interval off 0), both, or neither shown. An end within ``TOLERANCE`` of a bound is on it."""
  _, lo, hi = iv
  within = -margin - TOLERANCE <= lo and hi <= margin + TOLERANCE
  side = "ours below" if hi < -TOLERANCE else "ours above" if lo > TOLERANCE else None
  if within and side:
    return f"{side}, by less than {margin}"
  if within:
    return f"like the reference (within +-{margin})"
  if side:
    beyond = hi < -margin - TOLERANCE or lo > margin + TOLERANCE
    return f"{side}" + (f" by more than {margin}" if beyond else "")
  return "cannot be told apart"


def _reached(rows, method, x) -> bool:
  return any(r["method"] == method and int(r["env_step"]) >= x for r in rows)


def _level_reading(rows, method, estimator, reps):
  seeds, s_e, why = by_seed(rows, method, "eval_success", AT, AT)
  if why:
    return {"reading": f"n/a ({why})", "seeds": seeds}
  iv = stats.interval(estimator, s_e, reps=reps)
  return {"reading": versus_level(iv, PASS), "estimate": iv, "seeds": seeds,
          "values": s_e.tolist()}


def _difference(rows, column, lo, hi, reps):
  """ours - reference of the per-seed means of ``column`` over lo <= x <= hi, with the two
  sides' means; ``{"why": ...}`` where either side is not complete (``by_seed``)."""
  _, ours, why_ours = by_seed(rows, "ours", column, lo, hi)
  _, ref, why_ref = by_seed(rows, REFERENCE, column, lo, hi)
  if why_ours or why_ref:
    return {"why": "; ".join(f"{m}: {w}" for m, w in (("ours", why_ours),
                                                       ("the code", why_ref)) if w)}
  return {"difference": stats.interval(difference, ours, ref, reps=reps),
          "ours": stats.interval(mean, ours, reps=reps),
          "reference": stats.interval(mean, ref, reps=reps), "seeds": (len(ours), len(ref))}


def _modes(rows, method):
  """Each seed's Middle decisions per mode since warm-up at x = AT (its row there: our chunk's
  or the harness's window), or ``{"why": ...}`` where a seed has none."""
  at = {r["seed"]: r for r in rows if r["method"] == method
        and r.get("cum_decisions_TD3", "") != "" and int(r["env_step"]) == AT}
  seeds = seeds_of(rows, method)
  if len(seeds) != SEEDS[method] or set(at) != set(seeds):
    return {"why": f"{len(at)} of the protocol's {SEEDS[method]} seeds at x = {AT}"}
  return {m: np.array([float(at[s][f"cum_decisions_{m}"]) for s in seeds]) for m in MODES}


def readings(rows, reps=stats.REPS) -> dict:
  """R1-R6 from the rows of the reference and ours (``load``); a reading whose seeds are not
  all there (``by_seed``) is n/a with the reason."""
  if not any(r["method"] == REFERENCE for r in rows) or not any(r["method"] == "ours"
                                                                 for r in rows):
    raise ValueError(f"{TASK} rows of both the reference and ours are needed")
  out = {"reps": reps, "r1": _level_reading(rows, REFERENCE, mean, reps),
         "r2": _level_reading(rows, "ours", stats.iqm, reps),
         "r3": _difference(rows, "eval_success", *LATE, reps),
         "r4": _difference(rows, "eval_distance", *LATE, reps),
         "r5": {(column, x): _difference(rows, column, x - LOW_SPAN + 1, x, reps)
                for column in LOW_COLUMNS for x in LOW_AT
                if _reached(rows, "ours", x) and _reached(rows, REFERENCE, x)},
         "r6": {m: _modes(rows, m) for m in ("ours", REFERENCE)}}
  r3 = out["r3"]
  r3["reading"] = equivalence(r3["difference"]) if "difference" in r3 else f"n/a ({r3['why']})"
  return out


def _iv(iv, digits=2) -> str:
  return f"{iv[0]:.{digits}f} [{iv[1]:.{digits}f}, {iv[2]:.{digits}f}]"


def _diff_cell(d, digits=2) -> str:
  if "why" in d:
    return f"n/a ({d['why']})"
  return (f"ours {_iv(d['ours'], digits)} - reference {_iv(d['reference'], digits)} = "
          f"{_iv(d['difference'], digits)} ({d['seeds'][0]} and {d['seeds'][1]} seeds)")


def _level_cell(r) -> str:
  if "estimate" not in r:
    return ""
  return (f"{_iv(r['estimate'])} ({len(r['values'])} seeds); per seed "
          + ", ".join(f"{v:.2f}" for v in r["values"]))


def markdown(r: dict) -> str:
  how = ("every resample (exact)" if r["reps"] == "exact" else
         f"{r['reps']} replicates drawn with seed 0")
  lines = [f"Ant Push, the paper's code (reference) and ours, on the paper's axis (x = env "
           f"steps after the 100K warm-up). Intervals: 95 % stratified bootstrap, percentile, "
           f"{how}.", "", "| reading | result | numbers |", "|---|---|---|",
           f"| R1. the code's S_E at x = 1M, mean over seeds, passes {PASS} | "
           f"{r['r1']['reading']} | {_level_cell(r['r1'])} |",
           f"| R2. ours' S_E at x = 1M, IQM over seeds, passes {PASS} | {r['r2']['reading']} | "
           f"{_level_cell(r['r2'])} |"]
  r3 = r["r3"]
  lines.append(f"| R3. ours' late S_E (0.9M-1M) like the reference's (margin {MARGIN}) | "
               f"{r3['reading']} | {_diff_cell(r3)} |")
  lines.append(f"| R4. final distance to the target, late (described) | | "
               f"{_diff_cell(r['r4'])} |")
  for (column, x), d in r["r5"].items():
    lines.append(f"| R5. the Low's {LOW_COLUMNS[column]}, {LOW_SPAN // 1000}K up to x = "
                 f"{x // 1000}K (described) | | {_diff_cell(d)} |")
  for m, counts in r["r6"].items():
    cells = (f"n/a ({counts['why']})" if "why" in counts else
             ", ".join(f"{mode} {np.mean(counts[mode]):.0f} ("
                       + ", ".join(f"{v:.0f}" for v in counts[mode]) + ")" for mode in MODES))
    lines.append(f"| R6. {m}: Middle decisions per mode since warm-up, up to x = 1M, mean "
                 f"(per seed) (described) | | {cells} |")
  return "\n".join(lines) + "\n"


def is_study(dirs) -> bool:
  """Whether ``dirs`` hold reference runs (this study) rather than only run folders."""
  return any(reference_folders(d) for d in dirs)


# The figure (``figures``)
FIGURE = f"{TASK.lower()}_sidebyside"  # as experiments.plot names its figures
FIGURE_METHODS = (REFERENCE, "ours", "hiro")  # drawn in this order, those with rows
FIGURE_NAMES = {REFERENCE: "The paper's code"}  # the others: drawing.label
COLORS = {REFERENCE: "C3", "ours": "C0", "hiro": "C1"}
# A panel: (its column, title, y label, the bounds its band is clipped to)
PANELS = (("eval_success", f"(a) S_E, the {drawing.SUCCESS} at each evaluation (thin: each seed)",
           drawing.SUCCESS, (0, 1)),
          ("eval_distance", "(b) final distance to the target at each evaluation",
           "distance to the target", (0, np.inf)),
          ("low_reward", "(c) the Low's reward per env step", "reward per env step",
           (-np.inf, np.inf)),
          ("low_subgoal_progress", "(d) the Low's progress per segment, ||g_0|| - ||g_c||",
           "progress per segment", (-np.inf, np.inf)))


def figure_label(rows, method) -> str:
  """A method's name in the figure's legend with its seeds: ``The paper's code (3 seeds)``."""
  seeds = {r["seed"] for r in rows if r["method"] == method}
  return f"{FIGURE_NAMES.get(method, drawing.label(method))} ({drawing.seeds_text(len(seeds))})"


def panel_curves(rows, column, reps=stats.REPS) -> dict:
  """{method: (steps, mean, lower, upper, seeds)} of ``column`` for each of FIGURE_METHODS
  with a value of it: the mean over seeds and its pointwise 95 % stratified-bootstrap interval
  at the steps where every seed has a value (``curves.curves``; where one seed has got further
  than the others, its thin line in (a) shows the rest)."""
  out = {}
  for m in FIGURE_METHODS:
    curve = curves.curves(rows, TASK, m, column, reps)
    if len(curve[0]):
      out[m] = curve
  return out


def seed_lines(rows, method, column) -> dict:
  """{seed: (steps, values)}: ``column`` of each seed of ``method`` at each of its own steps
  with a value, in step order."""
  points = defaultdict(list)
  for r in rows:
    if r["method"] == method and r.get(column, "") != "":
      points[r["seed"]].append((int(r["env_step"]), float(r[column])))
  return {s: tuple(np.array(v) for v in zip(*sorted(points[s])))
          for s in sorted(points, key=curves.seed_order)}


def _panel(ax, rows, panel, labels, reps) -> bool:
  """One panel: each method's mean with its band (a method without the column left out);
  whether any was drawn."""
  column, title, ylabel, bounds = panel
  drawn = panel_curves(rows, column, reps)
  for m, curve in drawn.items():
    drawing.band(ax, curve, labels[m], COLORS[m], bounds=bounds)
  ax.set(title=title, xlabel=drawing.STEPS_LABEL, ylabel=ylabel, xlim=(0, AT))
  ax.grid(alpha=0.3)
  if not drawn:
    ax.text(0.5, 0.5, "no rows yet", transform=ax.transAxes, ha="center", color="0.4")
  return bool(drawn)


def _success_extras(ax, rows, labels):
  """Panel (a)'s seeds, thin under the means, and the paper's headline, dashed."""
  for m in labels:
    for steps, values in seed_lines(rows, m, "eval_success").values():
      ax.plot(steps, values, color=COLORS[m], lw=0.6, alpha=0.5, zorder=1)
  ax.axhline(PASS, color="0.3", ls="--", lw=1, label=f"the paper's headline, S_E {PASS}")
  ax.set_ylim(-0.05, 1.05)


def figures(rows, out, reps=stats.REPS) -> list[str]:
  """The study's figure ``FIGURE`` (PNG and PDF) from its rows (``load``) into folder ``out``:
  the reference, ours and HIRO (those with rows) on the paper's axis to x = AT, one panel per
  ``PANELS`` entry; (d) is left out while no method logs its column. The files written."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt

  rows = [r for r in rows if int(r["env_step"]) <= AT]
  labels = {m: figure_label(rows, m) for m in FIGURE_METHODS
            if any(r["method"] == m for r in rows)}
  os.makedirs(out, exist_ok=True)
  fig, axes = plt.subplots(2, 2, figsize=(11, 8))
  drawn = [_panel(ax, rows, panel, labels, reps) for ax, panel in zip(axes.flat, PANELS)]
  _success_extras(axes[0][0], rows, labels)
  if not drawn[3]:
    axes[1][1].remove()
  fig.suptitle(f"{TASK}: the paper's code and ours, mean over seeds, {drawing.INTERVAL}")
  drawing.legend_below(fig, fig.axes, 4)
  return drawing.finish(fig, out, FIGURE, curves.AXES["paper"])
