"""What the analyses read: the rows of run folders (``metrics.csv``), checked, merged across
folders, on the env's or the paper's step axis, per task, method and seed, and their mean
curves with 95 % intervals. ``experiments.plot``, ``claims``, ``calibrate``, ``render`` and
``sidebyside`` read runs through it."""

from __future__ import annotations

import csv
import json
import os
from collections import defaultdict

import numpy as np

from experiments import stats
from nonmono_jax.core.config import MODES  # the Middle's sub-policies (JAX-free)

# The step axes, by name, with the label a figure gives each. ``paper``: the paper's x-axis, env
# steps after the warm-up (its code logs each value at t - start_timestep, "All logs start
# after the first 100K steps").
AXES = {"env": "env steps", "paper": "env steps after the warm-up (the paper's axis)"}


REQUIRED = ("task", "method", "seed", "env_step", "eval_success", "eval_return",
            *(f"cum_steps_{m}" for m in MODES))


def load(dirs, axis: str = "env") -> list[dict]:
  """Every folder's rows, all checked before anything is drawn; raises ValueError naming the
  file and line. A half-written last line (a run killed mid-row) is skipped, as resume does.

  A folder is a run folder (with ``metrics.csv``) or holds run folders at any depth (a
  results tree such as ``results/pointpush/<method>/``). Folders that repeat a task and method
  (independent runs of a job array) add their seeds (``_merged``). ``axis="paper"``: each
  row's ``env_step`` is counted from the end of its run's warm-up (``paper_axis``), and the
  rows before it are left out."""
  if axis not in AXES:
    raise ValueError(f"axis must be one of {', '.join(AXES)}, got {axis!r}")
  rows, runs, paths = [], defaultdict(int), []  # (task, method) -> run folders seen with it
  for d in dirs:
    for path in _metrics_files(d):
      read = _read(path)
      rows.extend(_merged(paper_axis(read, path) if axis == "paper" else read, runs))
      paths.append(path)
  if not rows:
    raise ValueError(f"{', '.join(paths)}: no rows yet (no chunk of the run has finished): "
                     f"nothing to draw")
  return rows


def warmups(path: str) -> dict:
  """{method: its warm-up in env steps} from the ``config.json`` beside ``path`` (a
  ``metrics.csv``): ``warmup_steps`` x ``num_envs`` of each variant's config."""
  config = os.path.join(os.path.dirname(path), "config.json")
  try:
    with open(config) as f:
      configs = json.load(f)["configs"]
    return {m: int(c["warmup_steps"]) * int(c.get("num_envs", 1)) for m, c in configs.items()}
  except (OSError, ValueError, KeyError, TypeError) as e:
    raise ValueError(f"{config}: the paper's axis needs each run's warm-up from its config.json "
                     f"({type(e).__name__}: {e})") from None


def paper_axis(rows, path: str) -> list[dict]:
  """``rows`` of the ``metrics.csv`` at ``path`` on the paper's axis: ``env_step`` minus the
  run's warm-up (``warmups``), the rows inside the warm-up left out."""
  warm = warmups(path)
  missing = sorted({r["method"] for r in rows} - set(warm))
  if missing:
    raise ValueError(f"{path}: no warm-up for {', '.join(missing)} in its config.json")
  out = []
  for r in rows:
    step = int(r["env_step"]) - warm[r["method"]]
    if step > 0:
      out.append({**r, "env_step": str(step)})
  return out


def _merged(rows, runs) -> list[dict]:
  """A folder's rows, its seeds renamed ``k/seed`` if k earlier folders hold the same task and
  method (a job array of independent runs, ``--seed`` 0, 1, ...: their seeds merge into one
  set, not onto each other)."""
  keys = {(r["task"], r["method"]) for r in rows}
  earlier = {key: runs[key] for key in keys}
  for key in keys:
    runs[key] += 1
  return [r if not earlier[r["task"], r["method"]] else
          {**r, "seed": f"{earlier[r['task'], r['method']]}/{r['seed']}"} for r in rows]


def _metrics_files(d: str) -> list[str]:
  """``d/metrics.csv``, or else every ``metrics.csv`` below ``d`` (sorted)."""
  path = os.path.join(d, "metrics.csv")
  if os.path.isfile(path):
    return [path]
  found = sorted(os.path.join(root, "metrics.csv") for root, _, files in os.walk(d)
                 if "metrics.csv" in files)
  if not found:
    raise ValueError(f"{path} not found (is {d} a run folder?)")
  return found


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
    bad = [c for c in REQUIRED[4:] if values[header.index(c)] != ""
           and not np.isfinite(float(values[header.index(c)]))]
    if bad:
      raise ValueError(f"{path}: line {i + 2}: {bad[0]} is {values[header.index(bad[0])]} "
                       f"(not a finite number)")
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


def seed_order(seed: str):
  """Numeric order of seeds, a job array's folders one after the other (0, 1, ..., 10, then
  1/0, 1/1, ...: ``_merged``)."""
  return seed.count("/"), [int(part) for part in seed.split("/")]


def seed_table(rows, task, method, column):
  """(steps, seeds, values): the steps where every seed has a value of ``column``, those
  seeds in ``seed_order``, and their values (a row per seed, a column per step)."""
  by_step = defaultdict(dict)
  for r in rows:
    if r["task"] == task and r["method"] == method and r.get(column, "") != "":
      by_step[int(r["env_step"])][r["seed"]] = float(r[column])
  n_seeds = max((len(v) for v in by_step.values()), default=0)
  steps = sorted(s for s, v in by_step.items() if len(v) == n_seeds)
  seeds = sorted(by_step[steps[0]], key=seed_order) if steps else []
  values = np.array([[by_step[s][k] for s in steps] for k in seeds], dtype=float)
  return np.array(steps, dtype=int), seeds, values.reshape(len(seeds), len(steps))


def per_seed(rows, task, method, column):
  """(steps, values): ``column`` of each seed (a row of ``values``, in ``seed_ids`` order) at
  each step where every seed has a value (a column)."""
  steps, _, values = seed_table(rows, task, method, column)
  return steps, values


def seed_ids(rows, task, method, column="eval_success") -> list[str]:
  """The seeds of ``per_seed``'s rows of values, in numeric order."""
  return seed_table(rows, task, method, column)[1]


def curves(rows, task, method, column, reps: int = stats.REPS):
  """(steps, mean, lower, upper, seeds) over seeds of ``column``: the mean and its pointwise
  95 % stratified-bootstrap interval, at the steps where every seed has a value."""
  steps, values = per_seed(rows, task, method, column)
  if not len(steps):
    return np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), 0
  return (steps, *stats.mean_curve(values, reps=reps), len(values))
