"""The compiled side of a plan: its trainers, built once per group of variants, and whether
they fit in memory, checked before the run folder is made.

    programs = programs_lib.Programs(plan)        # a Plan stays data; this builds programs
    programs_lib.check_memory(plan, programs)     # ValueError naming what does not fit
    trainer = programs.trainer(["ours"])          # the memory check and the run share it
"""

from __future__ import annotations

import os

import jax
import numpy as np

from nonmono_jax.core import train
from nonmono_jax.host import checkpoints, plan as plan_lib
from nonmono_jax.host.plan import Plan

EVAL_RECORD_BYTES = 64  # an evaluation step's record (position, goal, blocks, success), about


class Programs:
  """One trainer per group of variants of ``plan`` (``train.make_group_trainer``: a variant
  alone is a group of one), built on first use."""

  def __init__(self, plan: Plan):
    self.plan = plan
    self._trainers: dict = {}

  def trainer(self, names) -> train.Trainer:
    names = (names,) if isinstance(names, str) else tuple(names)
    if names not in self._trainers:
      plan = self.plan
      env = plan.env()
      size = {"num_seeds": plan.spec.seeds, "chunk_steps": plan.spec.chunk}
      self._trainers[names] = train.make_group_trainer(env, [plan.configs[n] for n in names],
                                                       **size)
    return self._trainers[names]


def saved_method(run_dir: str, method: str | None = None) -> tuple[Plan, str, int]:
  """(plan, method, its newest checkpoint's step) of a run folder: the plan from its
  config.json (whatever today's presets say), ``method`` by default the run's first. Raises
  ValueError naming what is missing."""
  plan = plan_lib.load_run(run_dir)
  method = next(iter(plan.configs)) if method is None else method
  if method not in plan.configs:
    raise ValueError(f"method {method!r} is not in this run ({', '.join(plan.configs)})")
  ckpts = checkpoints.Checkpoints(os.path.join(run_dir, "checkpoints", method))
  try:
    step = ckpts.latest_step()
  finally:
    ckpts.close()
  if step is None:
    raise ValueError(f"no checkpoint of {method} in {run_dir} (the committed results hold "
                     "rows and configs only)")
  return plan, method, step


def restored(run_dir: str, method: str | None = None, step: int | None = None,
             plan: Plan | None = None):
  """(plan, method, step, trainer, states) of a saved run: ``method``'s train state (every
  seed on the leading axis) at the checkpoint of ``step``, by default the newest that
  restores; ``trainer`` is its program (``Programs(plan).trainer(method)``: its agent, env and
  lanes), built but not compiled. ``plan``: the run's, when the caller has it from
  ``saved_method`` (with ``method`` from there too), so the folder is read once."""
  if plan is None:
    plan, method, _ = saved_method(run_dir, method)
  elif method not in plan.configs:
    raise ValueError(f"method {method!r} is not in this run ({', '.join(plan.configs)})")
  trainer = Programs(plan).trainer(method)
  like = jax.eval_shape(trainer.init, jax.random.PRNGKey(0))
  ckpts = checkpoints.Checkpoints(os.path.join(run_dir, "checkpoints", method))
  try:
    if step is None:
      step, states = ckpts.restore_newest(like, move_aside=False)
    elif step in ckpts.manager.all_steps():
      states = ckpts.restore(step, like)
    else:
      raise ValueError(f"no checkpoint of {method} at step {step} in {run_dir} (it has "
                       f"{', '.join(map(str, sorted(ckpts.manager.all_steps())))})")
  finally:
    ckpts.close()
  return plan, method, step, trainer, states


def state_bytes(programs: Programs, names) -> int:
  """Bytes of the train state of a variant or group for all seeds (buffers, networks, envs):
  the shapes of ``trainer.init`` from ``jax.eval_shape``, so nothing is allocated."""
  shapes = jax.eval_shape(programs.trainer(names).init, jax.random.PRNGKey(0))
  return sum(int(np.prod(x.shape, dtype=np.float64)) * x.dtype.itemsize
             for x in jax.tree.leaves(shapes))


EXACT_FROM = 0.25  # a run estimated above this share of the memory is compiled to count it
MARGIN = 0.9  # the share of the available memory a run may take (the rest: Python, buffers)


def check_memory(plan: Plan, programs: "Programs | None" = None) -> None:
  """Refuses a run that cannot fit in the memory available (groups of variants run one after
  another: each is checked on its own). First an estimate (the train state and the
  evaluation's per-step records); a run estimated above ``EXACT_FROM`` of the memory is then
  compiled, and XLA's count of the chunk program (its state, temporaries and evaluation, per
  device, times the devices sharing this memory) must fit in ``MARGIN`` of it."""
  programs = programs or Programs(plan)
  have = available_bytes()
  spec = plan.spec
  for group in plan.groups():
    config, lanes = plan.configs[group[0]], spec.seeds * len(group)
    state = state_bytes(programs, group)
    evals = (lanes * config.num_envs * config.eval_episodes * spec.episode_length
             * EVAL_RECORD_BYTES)
    if have is not None and EXACT_FROM * have < state + evals <= have:
      _check_program(programs, group, have)
    if have is not None and state + evals > have:
      raise ValueError(f"{' + '.join(group)} for {spec.seeds} seeds needs "
                       f"{(state + evals) / 2**30:.1f} "
                       f"GiB (train state with its replay buffers {state / 2**30:.1f}, "
                       f"evaluation episodes {evals / 2**30:.1f}), more than the "
                       f"{have / 2**30:.1f} GiB available: use fewer --seeds, smaller "
                       f"buffers (--low.buffer_size, --middle.buffer_size) or shorter episodes")


def _check_program(programs: Programs, group, have: int) -> None:
  """XLA's count of the compiled chunk against ``MARGIN`` of the memory available."""
  devices = jax.local_device_count() if jax.default_backend() == "cpu" else 1
  need = programs.trainer(group).program_bytes()["total"] * devices
  if need > MARGIN * have:
    raise ValueError(f"{' + '.join(group)} for {programs.plan.spec.seeds} seeds needs "
                     f"{need / 2**30:.1f} "
                     f"GiB (XLA's count of the compiled chunk: train state, temporaries and "
                     f"evaluation), more than {MARGIN:.0%} of the {have / 2**30:.1f} GiB "
                     f"available: use fewer --seeds, smaller buffers (--low.buffer_size, "
                     f"--middle.buffer_size) or shorter episodes")


def available_bytes() -> int | None:
  """Memory the run may use: the devices' limit on an accelerator, else MemAvailable."""
  if jax.default_backend() != "cpu":
    stats = jax.devices()[0].memory_stats() or {}
    limit = stats.get("bytes_limit")
    return None if limit is None else limit * jax.device_count()
  try:
    with open("/proc/meminfo") as f:
      for line in f:
        if line.startswith("MemAvailable:"):
          return int(line.split()[1]) * 1024
  except OSError:
    pass
  try:
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
  except (ValueError, OSError):
    return None
