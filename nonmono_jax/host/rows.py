"""``metrics.csv``: its columns, a chunk's rows (formatted from the core's typed summary), and
the file, appended, checked and truncated on resume.

    rows = chunk_rows(task, method, env_step, summary, episode_length)   # one row per seed
    MetricsFile("out/metrics.csv").append(rows)

Long form: one row per method (variant), seed and chunk. Columns are added, never renamed or
moved, so a file an earlier version wrote is today's with some left out (``file_columns``): it
keeps its own header and its rows are written with its columns. A resumed run drops the rows
past the checkpoint it restarts from and a half-written last line (``MetricsFile.truncate``),
after checking that the rows up to it are one per seed and chunk (``check_rows``).
"""

from __future__ import annotations

import csv
import os
from typing import Iterable

import numpy as np

from nonmono_jax.core import hierarchy
from nonmono_jax.core.evaluate import KINDS as EVAL_KINDS
from nonmono_jax.core.summary import Summary
from nonmono_jax.host.folder import write_text

# Each learner's loss column: its value and its updates in the chunk (empty if none) of a Summary
LOSSES = {
    "low_critic_loss": lambda s: (s.losses.low_critic, s.updates.low),
    "low_actor_loss": lambda s: (s.losses.low_actor, s.updates.low),
    "middle_critic_loss": lambda s: (s.losses.middle_critic, s.updates.middle),
    "middle_actor_loss": lambda s: (s.losses.middle_actor, s.updates.middle),
    "middle_ppo_loss": lambda s: (s.losses.middle_ppo, s.updates.middle_ppo),
    "top_loss": lambda s: (s.losses.top, s.updates.top),
}
# the Low: mean reward per env step; at segment ends ||g_c||, whether it was <= 1.5 and
# ||g_0|| - ||g_c||
LOW = {"low_reward": lambda s: s.low_reward,
       "low_subgoal_distance": lambda s: s.subgoal_distance,
       "low_subgoal_reached": lambda s: s.subgoal_reached,
       "low_subgoal_progress": lambda s: s.subgoal_progress}
LOW_COLUMNS = tuple(LOW)
COLUMNS = (
    ("task", "method", "seed", "env_step", "eval_success", "eval_distance", "eval_return",
     "train_reward", "train_return", "train_success", "train_distance")
    + tuple(f"steps_{m}" for m in hierarchy.MODES)
    + tuple(f"cum_steps_{m}" for m in hierarchy.MODES)
    # Middle decisions (one per c env steps): the paper's unit for its mode counts
    + tuple(f"decisions_{m}" for m in hierarchy.MODES)
    + tuple(f"cum_decisions_{m}" for m in hierarchy.MODES)
    # the same after the starting mode (both units)
    + tuple(f"cum_steps_after_start_{m}" for m in hierarchy.MODES)
    + tuple(f"cum_decisions_after_start_{m}" for m in hierarchy.MODES)
    + tuple(f"p_{m}" for m in hierarchy.MODES)
    + tuple(LOSSES)
    # S_E of each evaluation kind (evaluate.KINDS), where the run evaluates it
    + tuple(f"eval_success_{kind}" for kind in EVAL_KINDS)
    + LOW_COLUMNS)


def chunk_rows(task: str, method: str, env_step: int, summary: Summary, episode_length: int,
               evaluated: bool = True) -> list[dict]:
  """One row per seed of a finished chunk, from its ``summary`` (``core.summary``, gathered:
  numpy arrays, one entry per seed).

  The eval columns hold the latest evaluation (empty until the first, ``evaluated``);
  ``train_reward`` is the mean task reward per env step over the chunk and ``train_return``
  that times the episode length (the return of the chunk's average training episode). A
  learner's loss is empty in a chunk where it did not update, pi_T where no Top horizon ended.
  """
  s = summary
  rows = []
  for seed in range(np.shape(s.reward)[0]):
    ev = (lambda x: x[seed]) if evaluated else (lambda x: "")
    row = {"task": task, "method": method, "seed": seed, "env_step": env_step,
           "eval_success": ev(s.s_e), "eval_distance": ev(s.eval_distance),
           "eval_return": ev(s.eval_return), "train_reward": s.reward[seed],
           "train_return": s.reward[seed] * episode_length, "train_success": s.success[seed],
           "train_distance": s.distance[seed]}
    for j, mode in enumerate(hierarchy.MODES):
      row[f"steps_{mode}"] = s.steps[seed, j]
      row[f"cum_steps_{mode}"] = s.cum_steps[seed, j]
      row[f"decisions_{mode}"] = s.decisions[seed, j]
      row[f"cum_decisions_{mode}"] = s.cum_decisions[seed, j]
      row[f"cum_steps_after_start_{mode}"] = s.cum_steps_after_start[seed, j]
      row[f"cum_decisions_after_start_{mode}"] = s.cum_decisions_after_start[seed, j]
      row[f"p_{mode}"] = s.mode_probs[seed, j] if s.horizons[seed] > 0 else ""
    for column, of in LOSSES.items():
      value, updates = of(s)
      row[column] = value[seed] if updates[seed] > 0 else ""
    for j, kind in enumerate(EVAL_KINDS):
      run = evaluated and s.evaluates[seed, j] > 0
      row[f"eval_success_{kind}"] = s.eval_by_kind[seed, j] if run else ""
    for column, of in LOW.items():
      row[column] = of(s)[seed]
    rows.append({k: (float(v) if isinstance(v, np.floating) else
                     int(v) if isinstance(v, np.integer) else v) for k, v in row.items()})
  return rows


class MetricsError(ValueError):
  """``metrics.csv`` is not a file this version wrote (one line naming the file)."""


class MetricsFile:
  """``metrics.csv``: rows appended and flushed to disk after every chunk; LF line endings
  always, so that a resumed run's file is byte for byte the one of a run that never stopped.
  A file written by an earlier version of the code, whose header lacks columns added since
  (``file_columns``), keeps its header: its rows are written with its columns."""

  def __init__(self, path: str):
    self.path = path
    if not os.path.exists(path):
      with open(path, "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerow(COLUMNS)
    self.columns = file_columns(path)

  def append(self, rows: Iterable[dict]) -> None:
    with open(self.path, "a", newline="") as f:
      w = csv.DictWriter(f, self.columns, lineterminator="\n", extrasaction="ignore")
      for row in rows:
        w.writerow(row)
      f.flush()
      os.fsync(f.fileno())

  def read(self) -> list[dict]:
    with open(self.path, newline="") as f:
      return list(csv.DictReader(f))

  def truncate(self, method: str, env_step: int) -> int:
    """Drop ``method``'s rows past ``env_step`` and a half-written last line; returns rows
    dropped. Raises MetricsError for a wrong header or a malformed line before the last."""
    keep, dropped = [",".join(self.columns)], 0
    for line in good_lines(self.path):
      row = dict(zip(self.columns, next(csv.reader([line]))))
      if row["method"] == method and int(row["env_step"]) > env_step:
        dropped += 1
        continue
      keep.append(line)
    write_text(self.path, "\n".join(keep) + "\n")
    return dropped


def check_rows(path: str, method: str, env_step: int, seeds: int, chunk_env_steps: int) -> None:
  """``method``'s rows up to ``env_step`` (its checkpoint's) are exactly one per seed and
  chunk, in order; raises MetricsError naming the first that is not (resume then refuses:
  rows lost or doubled would not come back)."""
  want = [(k * chunk_env_steps, seed) for k in range(1, env_step // chunk_env_steps + 1)
          for seed in range(seeds)]
  have, columns = [], file_columns(path)
  for line in good_lines(path):
    row = dict(zip(columns, next(csv.reader([line]))))
    if row["method"] == method and int(row["env_step"]) <= env_step:
      have.append((int(row["env_step"]), int(row["seed"])))
  if have == want:
    return
  i = next((i for i, (a, b) in enumerate(zip(have, want)) if a != b), min(len(have), len(want)))
  what = (f"seed {have[i][1]} at env step {have[i][0]} where seed {want[i][1]} at "
          f"{want[i][0]} belongs" if i < min(len(have), len(want)) else
          f"seed {want[i][1]} at env step {want[i][0]} is missing" if i < len(want) else
          f"seed {have[i][1]} at env step {have[i][0]} is one too many")
  raise MetricsError(f"{path}: {method} has {len(have)} rows up to env step {env_step}, where "
                     f"its checkpoint needs {len(want)} (one per seed and chunk); the first "
                     f"wrong one: {what}. Put back the file the run wrote, or start a new run")


KEY_COLUMNS = COLUMNS[:4]  # task, method, seed, env_step: what every version has, first


def _text(path: str) -> str:
  try:
    with open(path, newline="") as f:
      return f.read()
  except UnicodeDecodeError:
    raise MetricsError(f"{path}: not a text file") from None
  except OSError as e:
    raise MetricsError(f"{path}: cannot be read ({e.strerror or e})") from None


def file_columns(path: str) -> tuple[str, ...]:
  """The columns of a ``metrics.csv``: today's (``COLUMNS``), or those of an earlier version
  of the code, which are today's with some left out (columns are added, never renamed or
  moved); raises MetricsError for any other header."""
  lines = _text(path).splitlines()
  header = tuple(next(csv.reader(lines[:1]), []))
  known = [c for c in COLUMNS if c in header]
  if header[:len(KEY_COLUMNS)] != KEY_COLUMNS or list(header) != known:
    raise MetricsError(f"{path}: the header is not a metrics file's (not {', '.join(KEY_COLUMNS)}"
                       f", ... as this code or an earlier version writes it)")
  return header


def good_lines(path: str) -> list[str]:
  """The data lines of a ``metrics.csv``, without a half-written last line (one a kill cut
  short: no final newline, or the wrong number of fields); raises MetricsError otherwise."""
  text, n = _text(path), len(file_columns(path))
  lines = text.splitlines()[1:]
  if lines and (not text.endswith("\n") or not _well_formed(lines[-1], n)):
    lines = lines[:-1]
  for i, line in enumerate(lines):
    if not _well_formed(line, n):
      raise MetricsError(f"{path}: line {i + 2} is malformed: {line[:60]!r}")
  return lines


def _well_formed(line: str, n: int) -> bool:
  values = next(csv.reader([line]), [])
  if len(values) != n:
    return False
  try:
    return int(values[3]) >= 0  # env_step
  except ValueError:
    return False
