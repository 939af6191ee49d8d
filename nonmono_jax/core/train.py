"""The jitted core of training: chunks of env steps for every seed at once.

    trainer = make_trainer(env, agent_config, num_seeds=4, chunk_steps=2000)
    states = trainer.init(key)                      # one SeedState per seed (vmapped)
    for t0 in range(0, total, trainer.chunk_steps):  # Python: progress, logs, checkpoints
      states, metrics = trainer.chunk(states, t0)   # lax.scan over steps, vmap over seeds
    ev = trainer.evaluate(states, key, t)  # per seed, off the schedule: an Evaluation
    summary = trainer.summarise(states, metrics)  # what the rows say, typed (summary.py)

Inside a chunk the global step ``t`` is the scan's input and is not batched over seeds, so
every horizon gate in ``agent.step`` stays a real branch (docs/spec.md, section 6).
``metrics`` are per seed, reduced over the chunk as each declares (``metrics.Metric``): a level's
metrics (``low/critic_loss``, ``top/loss``, ``horizon/p_TD3``, ...) are averaged over the steps
where that level updated (``<level>/updated`` counts them), ``count/<mode>`` (env steps run in each
mode), ``decisions/<mode>`` (Middle decisions) and ``switch/switches`` are summed, the rest
(``reward``, ``low/reward``, ...) are averaged over all steps. Every metric the step computes
is in the reduced dict.

``chunk`` donates its input states (the buffers are updated in place): pass it states from
``init``, a previous ``chunk`` or a checkpoint, and do not reuse them after the call.

Variants as lanes (``make_group_trainer``): configs that share one static key
(``lanes.static_key``: they differ only in fields declared ``traced``, e.g. ours and its
three ablations, or a sweep of alpha) run as one program of V x S lanes, variant-major (lane
v * S + i is seed i of variant v), each lane reading its own ``lanes.Numbers``. Lane (v, i)
starts from the same key as seed i of variant v run alone, and a config run alone is a group
of one (its numbers are arguments too, never compile-time constants), so a lane computes bit
for bit the run of its variant alone.

    trainer = make_group_trainer(env, [ours, ours_no_mods], num_seeds=4, chunk_steps=2000)
    states = trainer.init(key)                      # 8 lanes
    states, metrics = trainer.chunk(states, 0)      # metrics["success"].shape == (8,)
    trainer.lanes(metrics, 1)                       # variant 1's seeds: (4,)


With several devices the lane axis is split across them (``jax.shard_map`` over a 1-D mesh
``seeds``): each device runs its own lanes, with no communication; the lane count must be a
multiple of the device count.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Callable, Mapping, Sequence

import jax
import jax.numpy as jp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from nonmono_jax.core import agent as agent_lib
from nonmono_jax.core import lanes
from nonmono_jax.core import metrics as metrics_lib
from nonmono_jax.core import summary as summary_lib


def compiled_bytes(compiled) -> dict:
  """Device memory of one compiled program, from XLA's own accounting: {"argument", "output",
  "temp", "alias", "total"} bytes, the total less what the outputs alias (donated inputs); {}
  where XLA keeps no count."""
  m = compiled.memory_analysis()
  if m is None:
    return {}
  out = {k: int(getattr(m, f"{k}_size_in_bytes")) for k in ("argument", "output", "temp", "alias")}
  return {**out, "total": out["argument"] + out["output"] + out["temp"] - out["alias"]}


@dataclasses.dataclass(frozen=True)
class Trainer:
  agent: agent_lib.Agent
  num_seeds: int  # seeds per variant
  chunk_steps: int
  mesh: Mesh
  init: Callable
  chunk: Callable
  evaluate: Callable
  variants: int = 1  # lanes = variants x num_seeds, variant-major
  # the jitted chunk(states, t0, hp) that ``chunk`` calls with the lanes' Numbers ``hp``
  chunk_program: Callable | None = None
  hp: Any = None
  # XLA's memory count of one device's compiled chunk (compiles it; compiled_bytes)
  program_bytes: Callable[[], dict] | None = None
  # compile(states, t0): compiles the chunk for these states ahead of its first call (which
  # then runs it), so that a caller can say how long compiling took
  compile: Callable | None = None
  # summarise(states, metrics) -> summary.Summary of a chunk, per lane (jitted)
  summarise: Callable = jax.jit(summary_lib.summarise)

  @property
  def num_lanes(self) -> int:
    return self.variants * self.num_seeds

  def lanes(self, tree, variant: int):
    """Variant ``variant``'s seeds of a per-lane pytree (states or metrics); the tree itself
    for a trainer of one variant (no copy)."""
    if self.variants == 1:
      return tree
    s = self.num_seeds
    return jax.tree.map(lambda x: x[variant * s:(variant + 1) * s], tree)


def reduce_chunk(metrics: dict) -> dict:
  """Per-step ``Metric``s (leading time axis) -> one array per name and seed (module doc)."""
  return metrics_lib.reduce(metrics, axis=0)


# XLA options the training chunk compiles with (a caller's ``compiler_options`` add to them
# and win; only the chunk, which is always called at the top level, where jit takes options).
# Region analysis lets XLA:CPU's copy insertion see that a weight updated in one ``cond``
# branch and passed through in the other needs no copy: the largest weights of every TD3 were
# copied once per step without it (the arithmetic is the same: docs/benchmarks.md). Other
# backends ignore it.
COMPILER_OPTIONS = {"xla_cpu_copy_insertion_use_region_analysis": True}


def make_trainer(env, config: agent_lib.AgentConfig, num_seeds: int, chunk_steps: int,
                 devices: Sequence[jax.Device] | None = None,
                 compiler_options: Mapping[str, Any] | None = None) -> Trainer:
  """Jitted ``init(key)``, ``chunk(states, t0)`` and ``evaluate(states, key)`` of one config:
  the group trainer of that one variant.

  ``compiler_options`` go to XLA with each program (``jax.jit``): e.g.
  ``{"xla_backend_optimization_level": 0}`` (LLVM -O0) compiles an MJX AntPush step in half
  the time on a CPU, for smoke tests that run a few steps; the point preset trains 2.5x slower
  at -O0.
  """
  return make_group_trainer(env, [config], num_seeds, chunk_steps, devices, compiler_options)


def make_group_trainer(env, configs: Sequence[agent_lib.AgentConfig], num_seeds: int,
                       chunk_steps: int, devices: Sequence[jax.Device] | None = None,
                       compiler_options: Mapping[str, Any] | None = None) -> Trainer:
  """One program for ``configs`` (equal ``lanes.static_key``s, else a ValueError naming the
  fields): ``len(configs) * num_seeds`` lanes, each with its variant's ``Numbers``."""
  key = lanes.check_group(list(configs))
  per_lane = jax.tree.map(lambda x: np.repeat(x, num_seeds, axis=0),
                          lanes.stack(list(configs)))
  return _make(env, key, per_lane, num_seeds, chunk_steps, devices, compiler_options,
               variants=len(configs))


def _with_step(evaluate):
  """``evaluate(states, key, t=0)``: ``t`` only sets the Middle PPO's std (the ``ppo`` kind)."""
  return lambda states, key, t=0: evaluate(states, key, jp.asarray(t, jp.int32))


def _make(env, config, per_lane, num_seeds, chunk_steps, devices, compiler_options,
          variants) -> Trainer:
  """The trainer of ``variants`` x ``num_seeds`` lanes, lane i reading ``per_lane``[i]."""
  for name, v in (("num_seeds", num_seeds), ("chunk_steps", chunk_steps)):
    if v < 1:
      raise ValueError(f"{name} must be >= 1, got {v}")
  devices = tuple(devices or jax.devices())
  if variants * num_seeds % len(devices):
    raise ValueError(f"variants x num_seeds ({variants} x {num_seeds}) must be a multiple of "
                     f"the device count ({len(devices)})")
  options = tuple(sorted((compiler_options or {}).items()))
  progs = _programs(env, config, num_seeds, variants, chunk_steps, devices, options)
  hp = jax.device_put(per_lane, progs.seeds)
  chunk = lambda states, t0: progs.chunk(states, t0, hp)
  lower = lambda states, t0=0: progs.chunk.lower(states, t0, hp)

  def program_bytes():
    return compiled_bytes(lower(jax.eval_shape(progs.init, jax.random.PRNGKey(0))).compile())

  def compile_for(states, t0):
    lower(states, t0).compile()
  return Trainer(
      agent=progs.agent, num_seeds=num_seeds, chunk_steps=chunk_steps, mesh=progs.mesh,
      init=progs.init, chunk=chunk, evaluate=progs.evaluate, variants=variants,
      chunk_program=progs.chunk, hp=hp, program_bytes=program_bytes, compile=compile_for)


@dataclasses.dataclass(frozen=True)
class _Programs:
  """The jitted functions of one program shape, shared by every trainer of that shape (their
  lanes' ``Numbers`` are arguments): the chunk takes ``(states, t0, hp)``."""
  agent: agent_lib.Agent
  mesh: Mesh
  seeds: NamedSharding  # the lane axis split over the mesh
  init: Callable
  chunk: Callable
  evaluate: Callable


# Programs kept per process (``_programs``): a run builds one per group of variants; a notebook
# or a test session that builds the same trainer again reuses its traced and compiled programs
# instead of tracing the agent again (seconds each: the persistent cache saves only XLA's part).
PROGRAMS_KEPT = 8


def forget_programs() -> None:
  """Drop the programs kept per process (``_programs``) and their compiled executables: a
  notebook or test session that is done with its trainers gives their memory back."""
  _programs.cache_clear()


@functools.lru_cache(maxsize=PROGRAMS_KEPT)
def _programs(env, key, num_seeds: int, variants: int, chunk_steps: int, devices: tuple,
              options: tuple) -> _Programs:
  """Jitted init, chunk and evaluate of ``env`` (by identity: ``plan.make_env`` keeps one per
  task and settings) and the static key ``key`` for ``variants`` x ``num_seeds`` lanes."""
  compiler_options = dict(options) or None
  agent = agent_lib.make_agent(env, key)
  mesh = Mesh(list(devices), ("seeds",))
  seeds = NamedSharding(mesh, P("seeds"))

  def local_chunk(states, t0, hp):
    body = lambda st, t: jax.vmap(agent.step, in_axes=(0, None, 0))(st, t, hp)
    states, metrics = jax.lax.scan(body, states, t0 + jp.arange(chunk_steps))
    return states, reduce_chunk(metrics)

  def local_evaluate(states, key, t):
    return jax.vmap(agent.evaluate, in_axes=(0, None, None))(states, t, key)

  shard = lambda f, in_specs: jax.shard_map(f, mesh=mesh, in_specs=in_specs,
                                             out_specs=P("seeds"), check_vma=False)

  def lane_keys(key):
    """Lane v * S + i from seed i's key: the same start as variant v run alone."""
    keys = jax.random.split(key, num_seeds)
    return jp.tile(keys, (variants, 1)) if variants > 1 else keys

  jit = functools.partial(jax.jit, compiler_options=compiler_options)
  # Each device initialises its own lanes, as it steps them (an env whose physics runs on the
  # host, envs.c_physics, is called back per device).
  sharded_init = jit(shard(jax.vmap(agent.init), (P("seeds"),)), out_shardings=seeds)
  keys_of = jit(lane_keys, out_shardings=seeds)

  # out_shardings: XLA would return zero-size leaves (an MJX model's empty mocap_pos, PointMaze's
  # blocks) replicated; kept split by lane, a chunk's output is its next input's sharding and the
  # chunk compiles once (not twice) and runs ahead-of-time compiled
  lanes_chunk = jax.jit(shard(local_chunk, (P("seeds"), P(), P("seeds"))), donate_argnums=0,
                        out_shardings=seeds,
                        compiler_options={**COMPILER_OPTIONS, **(compiler_options or {})})
  return _Programs(
      agent=agent, mesh=mesh, seeds=seeds, init=lambda key: sharded_init(keys_of(key)),
      chunk=lanes_chunk,
      evaluate=_with_step(jit(shard(local_evaluate, (P("seeds"), P(), P())))))
