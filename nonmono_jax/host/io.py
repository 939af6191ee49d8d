"""What a run leaves on disk: its folder, ``config.json``, ``metrics.csv`` and orbax checkpoints.

    out/config.json                 everything needed to rerun (configs, versions, device)
    out/metrics.csv                 long form: one row per method, seed and log step
    out/checkpoints/<method>/<step> orbax checkpoints of the vmapped train state
    out/timing.json                 the longest first (compiling) chunk, for --time-limit

Consistency under a kill at any moment (SIGKILL included): a chunk's metrics rows are written
and flushed before its checkpoint, orbax writes each checkpoint into a temporary folder that
it renames when complete, and ``MetricsFile.truncate`` drops, on resume, the rows past the
checkpoint the run restarts from (and a half-written last line).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io as _stdio
import json
import logging
import os
import shutil
import sys
import tempfile
import time
import warnings
from typing import Any, Iterable

import jax
import jax.numpy as jp
import numpy as np
import orbax.checkpoint as ocp
from flax import struct

from nonmono_jax.core import hierarchy
from nonmono_jax.core.evaluate import KINDS as EVAL_KINDS
from nonmono_jax.host import processes

LOSSES = ("low/critic_loss", "low/actor_loss", "middle/critic_loss", "middle/actor_loss",
          "middle_ppo/loss", "top/loss")
LOW_COLUMNS = ("low_reward", "low_subgoal_distance", "low_subgoal_reached",
               "low_subgoal_progress")
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
    + tuple(name.replace("/", "_") for name in LOSSES)
    # S_E of each evaluation kind (evaluate.KINDS), where the run evaluates it
    + tuple(f"eval_success_{kind}" for kind in EVAL_KINDS)
    # the Low: mean reward per env step; at segment ends ||g_c||, whether it was <= 1.5 and
    # ||g_0|| - ||g_c||
    + LOW_COLUMNS)


def to_jsonable(obj: Any) -> Any:
  """Dataclasses (configs) and tuples to plain JSON values."""
  if dataclasses.is_dataclass(obj):
    return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
  if isinstance(obj, (list, tuple)):
    return [to_jsonable(x) for x in obj]
  if isinstance(obj, dict):
    return {k: to_jsonable(v) for k, v in obj.items()}
  return obj


def write_text(path: str, text: str) -> None:
  """Atomically (a synced temporary file renamed over ``path``), line endings as given."""
  tmp = path + ".tmp"
  with open(tmp, "w", newline="") as f:
    f.write(text)
    f.flush()
    os.fsync(f.fileno())
  os.replace(tmp, path)


def write_json(path: str, payload: dict) -> None:
  """Atomically: a temporary file renamed over ``path``."""
  write_text(path, json.dumps(payload, indent=1, sort_keys=True))


def read_json(path: str) -> dict:
  with open(path) as f:
    return json.load(f)


@struct.dataclass
class RowCounters:
  """What a chunk's rows need of the train state: per lane, small (gathered from every
  process of a multi-process run, ``processes.gather``)."""

  mode_steps: Any
  mode_decisions: Any
  mode_steps_after_start: Any
  mode_decisions_after_start: Any
  s_e: Any
  eval_distance: Any
  eval_return: Any
  eval_by_kind: Any

  @classmethod
  def of(cls, states) -> "RowCounters":
    return cls(**{f.name: getattr(states, f.name) for f in dataclasses.fields(cls)})


def chunk_rows(task: str, method: str, env_step: int, states, metrics: dict,
               episode_length: int, evaluated: bool = True) -> list[dict]:
  """One metrics row per seed for a finished chunk (``metrics``: ``train.reduce_chunk``).

  The eval columns hold the latest evaluation (empty until the first, ``evaluated``);
  ``train_reward`` is the mean task reward per env step over the chunk and ``train_return``
  that times the episode length (the return of the chunk's average training episode).
  """
  m = jax.tree.map(np.asarray, metrics)
  cum = np.asarray(states.mode_steps)
  cumulative = {name: np.asarray(getattr(states, field)) for name, field in (
      ("cum_decisions", "mode_decisions"), ("cum_steps_after_start", "mode_steps_after_start"),
      ("cum_decisions_after_start", "mode_decisions_after_start"))}
  s_e, dist, ret = (np.asarray(x) for x in (states.s_e, states.eval_distance,
                                             states.eval_return))
  rows = []
  for seed in range(cum.shape[0]):
    ev = (lambda x: x[seed]) if evaluated else (lambda x: "")
    row = {"task": task, "method": method, "seed": seed, "env_step": env_step,
           "eval_success": ev(s_e), "eval_distance": ev(dist), "eval_return": ev(ret),
           "train_reward": m["reward"][seed],
           "train_return": m["reward"][seed] * episode_length, "train_success": m["success"][seed],
           "train_distance": m["distance"][seed]}
    for j, mode in enumerate(hierarchy.MODES):
      row[f"steps_{mode}"] = m[f"count/{mode}"][seed]
      row[f"cum_steps_{mode}"] = cum[seed, j]
      row[f"decisions_{mode}"] = m[f"decisions/{mode}"][seed]
      for name, values in cumulative.items():
        row[f"{name}_{mode}"] = values[seed, j]
      p = m.get(f"horizon/p_{mode}")
      row[f"p_{mode}"] = p[seed] if p is not None and m["horizon/updated"][seed] > 0 else ""
    for name in LOSSES:
      level = name.split("/")[0]
      ran = name in m and m[f"{level}/updated"][seed] > 0
      row[name.replace("/", "_")] = m[name][seed] if ran else ""
    kinds = np.asarray(states.eval_by_kind)
    for j, kind in enumerate(EVAL_KINDS):
      run = evaluated and f"eval/success_{kind}" in m
      row[f"eval_success_{kind}"] = kinds[seed, j] if run else ""
    for column in LOW_COLUMNS:
      row[column] = m[column.replace("_", "/", 1)][seed]
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


def _empty(x):
  """A leaf the checkpoint does not hold (zero-size, or added since) as an array: the
  template's own, or zeros for an abstract one."""
  if isinstance(x, jax.ShapeDtypeStruct):
    sharding = getattr(x, "sharding", None)
    zeros = jp.zeros(x.shape, x.dtype)
    return jax.device_put(zeros, sharding) if sharding is not None else zeros
  return x


class Checkpoints:
  """Orbax checkpoints of one method's train state, keyed by the vector step reached."""

  def __init__(self, directory: str, max_to_keep: int = 2, writer: bool = False):
    """``writer``: the run that owns the folder (its lock held) removes orbax's temporary
    folders of saves a kill cut short, which orbax would otherwise count as checkpoints."""
    # Synchronous saves: the next chunk donates (overwrites) the state being saved.
    self.directory = directory
    if writer and os.path.isdir(directory):
      for name in os.listdir(directory):
        if ".orbax-checkpoint-tmp" in name:
          shutil.rmtree(os.path.join(directory, name), ignore_errors=True)
    self.manager = ocp.CheckpointManager(
        os.path.abspath(directory),
        options=ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True,
                                             enable_async_checkpointing=False),
        # One item, said up front: otherwise orbax infers the layout from the latest step
        # folder, and one broken (emptied) folder makes every step fail to restore.
        item_handlers=ocp.StandardCheckpointHandler())

  def latest_step(self) -> int | None:
    return self.manager.latest_step()

  # Orbax cannot store zero-size arrays (a maze without blocks has a (seeds, envs, 0, 3)
  # ``blocks``): the checkpoint holds the other leaves by position, and a restore takes the
  # empty ones from the template.
  @staticmethod
  def _stored(leaves):
    return {str(i): x for i, x in enumerate(leaves) if np.prod(x.shape) > 0}

  def save(self, step: int, states) -> None:
    self.manager.save(step, args=ocp.args.StandardSave(self._stored(jax.tree.leaves(states))))
    self.manager.wait_until_finished()

  def restore(self, step: int, like):
    """The state saved at ``step``, shaped and placed like ``like`` (arrays or abstract).

    A checkpoint written before the state gained its last fields holds fewer leaves: the
    missing ones come from ``like`` (zeros where it is abstract), then the state's own
    ``filled(saved_leaves)``, if it has one, gives them the values that keep the run what it
    was (``agent.SeedState.filled``)."""
    leaves, treedef = jax.tree.flatten(like)
    saved = set(self.manager.item_metadata(step).keys())
    abstract = {k: jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=getattr(x, "sharding", None))
                for k, x in self._stored(leaves).items() if k in saved}
    got = self.manager.restore(step, args=ocp.args.StandardRestore(abstract))
    state = jax.tree.unflatten(treedef, [got.get(str(i), _empty(x))
                                         for i, x in enumerate(leaves)])
    n_saved = max((int(k) for k in saved), default=-1) + 1
    if n_saved < len(leaves) and hasattr(state, "filled"):
      state = state.filled(n_saved)
    return state

  def restore_newest(self, like, log=print, move_aside: bool = True):
    """(step, state) of the newest checkpoint that restores, or (None, ``like``) if there is
    none. Newer ones that do not restore are logged in one line each and (``move_aside``, the
    run's writer only) moved to ``<directory>.broken/``, kept, so that the run can save those
    steps again. Raises CheckpointError, moving nothing, if there were checkpoints and none
    restores."""
    steps, failed = sorted(self.manager.all_steps(), reverse=True), []
    with _stderr_dropped_if(lambda: failed):
      step, state = self._first_restoring(steps, like, failed)
    for bad, reason in failed:
      moved = f"; moved to {self._move_aside(bad)}" if move_aside and step is not None else ""
      log(f"skipped checkpoint {self.directory}/{bad} (it does not restore: {reason}){moved}")
    if step is None and steps:
      raise CheckpointError(f"no checkpoint in {self.directory} restores (step {failed[0][0]}: "
                            f"{failed[0][1]})")
    return step, state

  def _first_restoring(self, steps, like, failed):
    for step in steps:
      try:
        state = self.restore(step, like)
      except Exception as e:  # noqa: BLE001 - whatever orbax raises, the checkpoint is unusable
        failed.append((step, (str(e).strip().splitlines() or [type(e).__name__])[0][:160]))
        continue
      return step, state
    return None, like

  def set_aside_after(self, step: int, log=print) -> None:
    """Moves the checkpoints past ``step`` to ``<directory>.broken/`` (a run going back to
    ``step``, which will save those steps again)."""
    for newer in [s for s in self.manager.all_steps() if s > step]:
      log(f"set aside checkpoint {self.directory}/{newer} (its group restarts from step "
          f"{step}); moved to {self._move_aside(newer)}")

  def _move_aside(self, step: int) -> str:
    aside = os.path.join(self.directory + ".broken", f"{step}-{time.strftime('%Y%m%d-%H%M%S')}")
    os.makedirs(os.path.dirname(aside), exist_ok=True)
    os.replace(os.path.join(self.directory, str(step)), aside)
    self.manager.reload()
    return aside

  def close(self) -> None:
    self.manager.close()


_LEFTOVER_SOURCES = ("orbax", "tensorstore", "asyncio")


def quiet_storage_leftovers() -> None:
  """Drops what orbax's storage layer leaves behind after a failed save or restore: its
  coroutines and callbacks that fail later, on their own threads or when the interpreter
  exits ("Exception ignored in: <coroutine ...>", "RuntimeError: Event loop is closed"), which
  Python prints through ``sys.unraisablehook`` after the command has said what failed in one
  line, and the error logs of absl and asyncio, through which orbax reports each failed write.
  Every other unraisable exception is printed as before. The experiment command and
  ``render`` install it (not with ``NONMONO_TRACEBACK=1``, which shows everything)."""
  if os.environ.get("NONMONO_TRACEBACK"):
    return
  previous = sys.unraisablehook
  if getattr(previous, "storage_leftovers", False):
    return
  # orbax logs each failed write or read through absl ("ERROR:absl:... raised an exception"),
  # asyncio each of its futures whose failure nobody retrieved: hundreds of lines for one
  # failure that the command reports in one
  for name in ("absl", "asyncio"):
    logging.getLogger(name).setLevel(logging.CRITICAL)
  # and coroutines of an aborted save that nobody awaits any more, reported at exit
  warnings.filterwarnings("ignore", message="coroutine .* was never awaited",
                          category=RuntimeWarning)

  def hook(unraisable):
    frames = []
    tb = unraisable.exc_traceback
    while tb is not None:
      frames.append(tb.tb_frame.f_code.co_filename)
      tb = tb.tb_next
    where = " ".join(frames) + " " + repr(unraisable.object)
    if any(source in where for source in _LEFTOVER_SOURCES) or \
        "Event loop is closed" in str(unraisable.exc_value):
      return
    previous(unraisable)

  hook.storage_leftovers = True
  sys.unraisablehook = hook


@contextlib.contextmanager
def _stderr_dropped_if(failed):
  """Holds back what the block writes to file descriptor 2 and drops it if ``failed()``: a
  failed orbax restore leaves tensorstore callbacks that print hundreds of "Event loop is
  closed" tracebacks (some after the restore returns), where the caller says what failed in
  one line. Otherwise it is let through."""
  sys.stderr.flush()
  saved, python_stderr, held_text = os.dup(2), sys.stderr, _stdio.StringIO()
  with tempfile.TemporaryFile() as held:
    os.dup2(held.fileno(), 2)
    sys.stderr = held_text  # the callbacks print through Python's sys.stderr
    try:
      yield
    finally:
      sys.stderr = python_stderr
      os.dup2(saved, 2)
      os.close(saved)
      if not failed():
        held.seek(0)
        os.write(2, held.read())
        sys.stderr.write(held_text.getvalue())


class CheckpointError(RuntimeError):
  """No checkpoint of a method restores."""


@jax.jit
def _finite(parts: dict) -> dict:
  """Per part, per lane: every value finite (computed where the lanes live)."""
  return {k: jax.tree.reduce(jp.logical_and, jax.tree.map(
      lambda x: jp.all(jp.isfinite(x), axis=tuple(range(1, x.ndim))), v))
          for k, v in parts.items()}


def first_non_finite(states, metrics: dict) -> tuple[int, str] | None:
  """(seed, where) of the first NaN or Inf in the learners' parameters or the chunk's losses
  (the per-lane verdicts gathered from every process of a multi-process run)."""
  finite = processes.gather(_finite(dict(_learner_params(states))))
  levels = set(finite)
  for name, value in metrics.items():  # per lane already (gathered by the caller)
    if name.split("/")[0] in levels or name in ("reward",):
      v = np.asarray(value)
      finite[f"metric {name}"] = np.isfinite(v.reshape(v.shape[0], -1)).all(axis=1)
  n = np.asarray(next(iter(finite.values()))).shape[0] if finite else 0
  for seed in range(n):
    for name, ok in finite.items():
      if not ok[seed]:
        return seed, name
  return None


def _learner_params(states) -> dict:
  """The learners' parameters by level name: ``SeedState.learner_params()``; for a state
  without it, those of its ``low``, ``middle``, ``middle_ppo`` and ``top`` that it has."""
  if hasattr(states, "learner_params"):
    return states.learner_params()
  levels = ("low", "middle", "middle_ppo", "top")
  return {level: getattr(states, level).params for level in levels
          if getattr(getattr(states, level, None), "params", None) is not None}
