"""Orbax checkpoints of a variant's train state, keyed by the vector step reached.

    ckpts = Checkpoints("out/checkpoints/ours", writer=True)
    ckpts.save(step, states)                       # synchronous: the next chunk donates states
    step, states = ckpts.restore_newest(like)      # the newest that restores, or (None, like)

Consistency under a kill at any moment (SIGKILL included): a chunk's rows are written and
flushed before its checkpoint (``run.py``), orbax writes each checkpoint into a temporary
folder that it renames when complete, and the writer removes the temporary folders of saves a
kill cut short. A checkpoint written before the state gained its last fields restores with
them filled as that code behaved (``agent.SeedState.filled``). What orbax's storage layer
leaves behind after a failed save or restore is kept off the terminal
(``quiet_storage_leftovers``).
"""

from __future__ import annotations

import contextlib
import io as _stdio
import logging
import os
import shutil
import sys
import tempfile
import time
import warnings

import jax
import jax.numpy as jp
import numpy as np
import orbax.checkpoint as ocp


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
