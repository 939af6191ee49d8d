"""The run folder's logs: the per-evaluation CSV, the every-window CSV and the JSONL of every
``wandb.log`` call, each cut back to a checkpoint's step when a run resumes.

Every row carries the env step ``t`` of the loop iteration it was written in. A checkpoint at
the top of iteration ``t_c`` keeps the JSONL and evaluation rows of iterations ``< t_c`` and
the window rows of ``t <= t_c`` (the window row of ``t_c`` is written just before the
checkpoint), so a resumed run's files equal an uninterrupted run's, timing columns aside.
"""

import csv
import json
import os

EVAL_COLUMNS = (
    "t", "step", "success_rate", "higher_success_rate", "final_distance",
    "final_distance_ppo", "successes", "successes_ppo", "eval_mode", "eval_s", "eval_ppo_s",
    "train_steps_per_s", "wall_s")
WINDOW_COLUMNS = (
    "t", "step", "low_intrinsic_reward_mean", "low_reward_steps", "on_policy_count",
    "off_policy_count", "random_policy_count", "episode_num_h", "success_rate",
    "higher_success_rate", "mujoco_warnings", "train_steps_per_s", "wall_s",
    # per segment ended in the window: the Low's subgoal at its start, ||g_0||, at its end,
    # ||g_c||, whether ||g_c|| <= 1.5, and ||g_0|| - ||g_c|| (means); added 2026-12-05
    "segments", "subgoal_start", "subgoal_distance", "subgoal_reached", "subgoal_progress",
    # training env steps per CPU-second of the process (evaluation and checkpoints left out)
    "train_steps_per_cpu_s")
# Columns that measure time; they differ between runs and are left out of comparisons.
TIMING = ("eval_s", "eval_ppo_s", "train_steps_per_s", "train_steps_per_cpu_s", "wall_s")


def _cut_csv(path, keep):
  if not os.path.exists(path):
    return
  with open(path, newline="") as f:
    rows = list(csv.DictReader(f))
    columns = None if not rows else list(rows[0].keys())
  if columns is None:
    return
  with open(path, "w", newline="") as f:
    writer = csv.DictWriter(f, columns)
    writer.writeheader()
    writer.writerows(row for row in rows if keep(int(row["t"])))


def _cut_jsonl(path, keep):
  if not os.path.exists(path):
    return
  with open(path) as f:
    lines = [line for line in f if line.strip() and keep(json.loads(line)["_t"])]
  with open(path, "w") as f:
    f.writelines(lines)


def _widen(path, columns):
  """A file written by an older harness, whose header is the first of ``columns``: rewritten
  with all of them, its rows' new columns empty, so that appended rows line up."""
  if not os.path.exists(path) or os.path.getsize(path) == 0:
    return
  with open(path, newline="") as f:
    rows = list(csv.reader(f))
  header = tuple(rows[0])
  if header == tuple(columns):
    return
  if header != tuple(columns[:len(header)]):
    raise ValueError(f"{path}: its columns are not this harness's ({', '.join(header)})")
  with open(path, "w", newline="") as f:
    writer = csv.writer(f)
    writer.writerow(columns)
    writer.writerows(row + [""] * (len(columns) - len(header)) for row in rows[1:])


class Logs:
  """The three files of a run folder, opened for appending after being cut back to ``t0``."""

  def __init__(self, folder, t0):
    self.eval_path = os.path.join(folder, "evaluations.csv")
    self.window_path = os.path.join(folder, "windows.csv")
    self.jsonl_path = os.path.join(folder, "wandb.jsonl")
    _cut_csv(self.eval_path, lambda t: t < t0)
    _cut_csv(self.window_path, lambda t: t <= t0)
    _cut_jsonl(self.jsonl_path, lambda t: t < t0)
    self._eval = self._open_csv(self.eval_path, EVAL_COLUMNS)
    self._window = self._open_csv(self.window_path, WINDOW_COLUMNS)
    self._jsonl = open(self.jsonl_path, "a")

  @staticmethod
  def _open_csv(path, columns):
    _widen(path, columns)
    new = not os.path.exists(path) or os.path.getsize(path) == 0
    f = open(path, "a", newline="")
    writer = csv.DictWriter(f, columns)
    if new:
      writer.writeheader()
    return f, writer

  def evaluation(self, row):
    self._eval[1].writerow(row)
    self._eval[0].flush()

  def window(self, row):
    self._window[1].writerow(row)
    self._window[0].flush()

  def wandb(self, t, step, record):
    self._jsonl.write(json.dumps({"_t": t, "_step": step, **record}) + "\n")

  def flush(self):
    for f in (self._eval[0], self._window[0], self._jsonl):
      f.flush()

  def close(self):
    for f in (self._eval[0], self._window[0], self._jsonl):
      f.close()


def read_csv(path, drop=TIMING):
  """A CSV's rows as dicts of strings, without the timing columns."""
  with open(path, newline="") as f:
    return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]
