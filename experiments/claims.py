"""The Ant Push studies' readings, as their protocols state them: the first study
(``results/antpush/README.md``) here, the decisive side-by-side one with the paper's code
(``results/antpush_reference/README.md``) in ``experiments/sidebyside.py``, picked when the
folders hold the reference harness's runs.

    python -m experiments.claims results/antpush          # prints the readings as markdown
    python -m experiments.claims results/antpush --reps exact   # every resample, no draw
    python -m experiments.claims results/antpush --axis paper   # steps after the warm-up

Each claim is judged from the run folders' ``metrics.csv`` rows (ours and HIRO, S_E of 50
episodes every 10K steps) with the statistics of ``experiments.stats`` (IQM over seeds, the
probability of improvement, 95 % stratified-bootstrap intervals):

1. S_E passes 0.6 at 1M: the IQM of final S_E against 0.6;
2. S_E occurs from about 500K: each seed's mean S_E over the evaluations from 500K to 600K;
3. HIRO best early (at a quarter of the run), then behind (at the end);
4. the Top's mode counts after the starting mode, in Middle decisions, and "most PPO before 1M"
   (half the paper's ~3600 PPO decisions).

Written (and tested on made-up rows) before the study's results existed; a reading that the
protocol does not define is not made here. The protocol's intervals are 2000 replicates
(``stats.REPS``, the default, each drawn with seed 0); ``--reps`` takes more, or "exact" for
every resample (``experiments/stats.py``), where a reading sits on the Monte Carlo edge.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from experiments import curves, plot, sidebyside, stats

TASK = "AntPush"
END = 1_000_000  # the protocol's budget: claims 1 and 4 are read there
EARLY = 250_000  # "early": a quarter of the run
PASS_AT_END = 0.6
WINDOW = (500_000, 600_000)  # "occurs from about 500K": present by 600K
PAPER_PPO_DECISIONS = 3600  # "about 3600" after the starting mode, over the paper's 3.15M steps


def versus(interval, level: float, above: str, below: str) -> str:
  """``above`` if the interval lies at or above ``level``, ``below`` if it lies below, else
  "cannot be told apart"."""
  _, lo, hi = interval
  if lo >= level:
    return above
  if hi < level:
    return below
  return "cannot be told apart"


def improvement(p) -> str:
  """P(A > B) read as the study does: holds if its interval lies above 0.5, does not hold if
  below, else cannot be told apart."""
  return "holds" if p[1] > 0.5 else "does not hold" if p[2] < 0.5 else "cannot be told apart"


def final_reading(run: tuple, reps=stats.REPS) -> dict:
  """Claim 1: the IQM of S_E at ``END`` against 0.6 (and whether it lies above 0), the mean;
  before ``END``, the same at the latest evaluation, described, not judged."""
  steps, values = run
  iv = stats.interval(stats.iqm, values[:, -1], reps=reps)
  judged = int(steps[-1]) >= END
  return {"iqm": iv, "mean": float(values[:, -1].mean()), "step": int(steps[-1]),
          "reading": (versus(iv, PASS_AT_END, "holds", "does not hold") if judged else
                      f"n/a (at {int(steps[-1])} of {END})"),
          "above_zero": bool(iv[1] > 0)}


def onset_reading(steps: np.ndarray, values: np.ndarray, reps=stats.REPS) -> dict:
  """Claim 2: presence by 600K (the window's per-seed means), and where S_E first shows."""
  inside = (steps >= WINDOW[0]) & (steps <= WINDOW[1])
  if steps[-1] < WINDOW[1]:
    return {"reading": f"n/a (at {int(steps[-1])}: read at {WINDOW[1]})"}
  iv = stats.interval(stats.iqm, values[:, inside].mean(1), reps=reps)
  upto = steps <= WINDOW[1]
  if iv[1] > 0:
    reading = "holds"
  elif not values[:, upto].any():
    reading = "does not hold"
  else:
    reading = "cannot be told apart"
  curve = stats.iqm_curve(values, reps=reps)
  first_ci = steps[np.flatnonzero(curve[1] > 0)] if (curve[1] > 0).any() else []
  first_any = steps[np.flatnonzero(values.max(0) > 0)] if values.any() else []
  return {"window_iqm": iv, "reading": reading,
          "first_step_iqm_above_0": int(first_ci[0]) if len(first_ci) else None,
          "first_step_any_seed": int(first_any[0]) if len(first_any) else None}


def _at(run: tuple, step: int):
  """Every seed's S_E at ``step`` (None if the run has not reached it)."""
  steps, values = run
  hit = np.flatnonzero(steps == step)
  return values[:, hit[0]] if hit.size else None


def early_late_reading(ours: tuple, hiro: tuple | None, reps=stats.REPS) -> dict:
  """Claim 3: P(HIRO > ours) at ``EARLY``, P(ours > HIRO) at ``END`` (n/a before, and
  without HIRO's rows)."""
  why = "n/a (not reached)" if hiro is not None else "n/a (no rows of HIRO)"
  out = {"early_step": EARLY, "early": why, "behind": why, "p_hiro_early": None,
         "p_ours_end": None}
  if hiro is None:
    return out
  o, h = _at(ours, EARLY), _at(hiro, EARLY)
  if o is not None and h is not None:
    out["p_hiro_early"] = stats.interval(stats.probability_of_improvement, h, o, reps=reps)
    out["early"] = improvement(out["p_hiro_early"])
  o, h = _at(ours, END), _at(hiro, END)
  if o is not None and h is not None:
    out["p_ours_end"] = stats.interval(stats.probability_of_improvement, o, h, reps=reps)
    out["behind"] = improvement(out["p_ours_end"])
  return out


def modes_reading(summary_row: dict) -> dict:
  """Claim 4: the modes' order (plot.mode_order) and PPO decisions against 1800, at ``END``
  (before it: described, not judged)."""
  ppo = summary_row["decisions_after_start_PPO"]
  half = PAPER_PPO_DECISIONS / 2
  judged = summary_row["env_steps"] >= END
  order = plot.mode_order(summary_row)
  return {"order": order if judged else f"{order} (at {summary_row['env_steps']}, not judged)",
          "ppo": ppo, "td3": summary_row["decisions_after_start_TD3"],
          "random": summary_row["decisions_after_start_RANDOM"],
          "most_ppo_before_1m": (versus(ppo, half, "holds", "does not hold") if judged else
                                 f"n/a (at {summary_row['env_steps']} of {END})")}


def readings(rows, reps=stats.REPS, axis: str = "env") -> dict:
  """Every claim's reading from the rows of ours and HIRO on AntPush; without HIRO's rows
  (the side-by-side study's ours before its HIRO runs), claims 1, 2 and 4 of ours, and 3 n/a.
  ``reps``: the bootstrap replicates of every interval (the protocol's 2000 by default), or
  "exact"."""
  ours = curves.per_seed(rows, TASK, "ours", "eval_success")
  hiro = curves.per_seed(rows, TASK, "hiro", "eval_success")
  if not len(ours[0]):
    raise ValueError(f"{TASK} rows of ours are needed")
  hiro = hiro if len(hiro[0]) else None
  summary = {r["method"]: r for r in plot.summary(rows, reps=reps) if r["task"] == TASK}
  runs = (("ours", ours),) + ((("hiro", hiro),) if hiro is not None else ())
  return {"steps": int(ours[0][-1]), "reps": reps, "axis": axis,
          "seeds": (len(ours[1]), len(hiro[1]) if hiro is not None else 0),
          "final": {m: final_reading(v, reps) for m, v in runs},
          "onset": onset_reading(*ours, reps=reps),
          "early_late": early_late_reading(ours, hiro, reps),
          "modes": modes_reading(summary["ours"])}


def _iv(iv, digits=2) -> str:
  return f"{iv[0]:.{digits}f} [{iv[1]:.{digits}f}, {iv[2]:.{digits}f}]"


def markdown(r: dict) -> str:
  f, o, e, m = r["final"], r["onset"], r["early_late"], r["modes"]
  lines = [
      (f"Ant Push, ours and HIRO at {r['steps']} {curves.AXES[r.get('axis', 'env')]} "
       f"({r['seeds'][0]} and {r['seeds'][1]} seeds)" if "hiro" in f else
       f"Ant Push, ours at {r['steps']} {curves.AXES[r.get('axis', 'env')]} "
       f"({r['seeds'][0]} seeds; no rows of HIRO)")
      + ". Intervals: 95 % stratified bootstrap, percentile, "
      + ("every resample (exact)." if r["reps"] == "exact" else
         f"{r['reps']} replicates drawn with seed 0."), "",
      "| claim | reading | numbers |", "|---|---|---|",
      f"| 1. ours' S_E passes 0.6 at 1M | {f['ours']['reading']} | IQM of S_E at "
      f"{f['ours']['step']} "
      f"{_iv(f['ours']['iqm'])} ({'above' if f['ours']['above_zero'] else 'not above'} 0), "
      f"mean {f['ours']['mean']:.2f}"
      + (f"; HIRO {_iv(f['hiro']['iqm'])}, mean {f['hiro']['mean']:.2f}" if "hiro" in f
         else "") + " |"]
  if "window_iqm" in o:
    lines.append(f"| 2. ours' S_E occurs from about 500K | {o['reading']} | IQM of each seed's "
                 f"mean S_E over 500K-600K {_iv(o['window_iqm'])}; first evaluation with the "
                 f"IQM's interval above 0: {o['first_step_iqm_above_0']}; with any seed above "
                 f"0: {o['first_step_any_seed']} |")
  else:
    lines.append(f"| 2. ours' S_E occurs from about 500K | {o['reading']} | |")
  lines += [
      f"| 3a. HIRO best early ({e['early_step']}) | {e['early']} | "
      + (f"P(HIRO > ours) {_iv(e['p_hiro_early'])}" if e["p_hiro_early"] else "") + " |",
      f"| 3b. then behind ours ({END}) | {e['behind']} | "
      + (f"P(ours > HIRO) {_iv(e['p_ours_end'])}" if e["p_ours_end"] else "") + " |",
      f"| 4a. modes after the starting mode: TD3 >> PPO > RANDOM | {m['order']} | Middle "
      f"decisions of TD3 {_iv(m['td3'], 0)}, PPO {_iv(m['ppo'], 0)}, RANDOM "
      f"{_iv(m['random'], 0)} |",
      f"| 4b. most of the paper's ~3600 PPO decisions before 1M | {m['most_ppo_before_1m']} | "
      f"PPO decisions {_iv(m['ppo'], 0)} against 1800 |"]
  return "\n".join(lines) + "\n"


def _reps(text: str):
  """--reps: a positive integer or "exact"."""
  if text == "exact":
    return text
  try:
    n = int(text)
  except ValueError:
    n = 0
  if n < 1:
    raise argparse.ArgumentTypeError(f"a positive integer or 'exact', got {text!r}")
  return n


def main(argv=None) -> int:
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("dirs", nargs="+", help="run folders, or folders holding them")
  p.add_argument("--reps", type=_reps, default=stats.REPS,
                 help=f"bootstrap replicates of every interval (default {stats.REPS}, the "
                 "protocol's), or 'exact' for every resample")
  p.add_argument("--axis", choices=tuple(curves.AXES), default="env",
                 help="read the claims' steps (1M, 250K, 500K-600K) as env steps (the "
                      "protocol's, default) or on the paper's axis, after the warm-up (1M there "
                      "is env step 1.1M)")
  args = p.parse_args(argv)
  try:
    if sidebyside.is_study(args.dirs):  # on the paper's axis by its protocol
      print(sidebyside.markdown(sidebyside.readings(sidebyside.load(args.dirs), args.reps)),
            end="")
      return 0
    rows = curves.load(args.dirs, args.axis)
    print(markdown(readings(rows, reps=args.reps, axis=args.axis)), end="")
  except ValueError as e:
    print(f"error: {e}", file=sys.stderr)
    return 2
  return 0


if __name__ == "__main__":
  sys.exit(main())
