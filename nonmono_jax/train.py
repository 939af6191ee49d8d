"""The jitted core of training: chunks of env steps for every seed at once.

    trainer = make_trainer(env, agent_config, num_seeds=4, chunk_steps=2000)
    states = trainer.init(key)                      # one SeedState per seed (vmapped)
    for t0 in range(0, total, trainer.chunk_steps):  # Python: progress, logs, checkpoints
      states, metrics = trainer.chunk(states, t0)   # lax.scan over steps, vmap over seeds
    s_e, dist, ret = trainer.evaluate(states, key)  # per seed, outside the schedule

Inside a chunk the global step ``t`` is the scan's input and is not batched over seeds, so
every horizon gate in ``agent.step`` stays a real branch (SPEC section 6). ``metrics`` are per
seed, reduced over the chunk as each declares (``metrics.Metric``): a level's metrics
(``low/critic_loss``, ``top/loss``, ``horizon/p_TD3``, ...) are averaged over the steps where
that level updated (``<level>/updated`` counts them), ``count/<mode>`` (env steps run in each
mode), ``decisions/<mode>`` (Middle decisions) and ``switch/switches`` are summed, the rest
(``reward``, ``low/reward``, ...) are averaged over all steps. Every metric the step computes
is in the reduced dict.

``chunk`` donates its input states (the buffers are updated in place): pass it states from
``init``, a previous ``chunk`` or a checkpoint, and do not reuse them after the call.

With several devices the seed axis is split across them (``jax.shard_map`` over a 1-D mesh
``seeds``): each device runs its own seeds, with no communication; ``num_seeds`` must be a
multiple of the device count.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Callable, Mapping, Sequence

import jax
import jax.numpy as jp
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from nonmono_jax import agent as agent_lib
from nonmono_jax import metrics as metrics_lib


@dataclasses.dataclass(frozen=True)
class Trainer:
  agent: agent_lib.Agent
  num_seeds: int
  chunk_steps: int
  mesh: Mesh
  init: Callable
  chunk: Callable
  evaluate: Callable


def reduce_chunk(metrics: dict) -> dict:
  """Per-step ``Metric``s (leading time axis) -> one array per name and seed (module doc)."""
  return metrics_lib.reduce(metrics, axis=0)


def make_trainer(env, config: agent_lib.AgentConfig, num_seeds: int, chunk_steps: int,
                 devices: Sequence[jax.Device] | None = None,
                 compiler_options: Mapping[str, Any] | None = None) -> Trainer:
  """Jitted ``init(key)``, ``chunk(states, t0)`` and ``evaluate(states, key)``.

  ``compiler_options`` go to XLA with each program (``jax.jit``): e.g.
  ``{"xla_backend_optimization_level": 0}`` halves the CPU compile of an MJX ant trainer, for
  smoke tests that run a few steps.
  """
  for name, v in (("num_seeds", num_seeds), ("chunk_steps", chunk_steps)):
    if v < 1:
      raise ValueError(f"{name} must be >= 1, got {v}")
  devices = list(devices or jax.devices())
  if num_seeds % len(devices):
    raise ValueError(f"num_seeds ({num_seeds}) must be a multiple of the device count "
                     f"({len(devices)})")
  agent = agent_lib.make_agent(env, config)
  mesh = Mesh(devices, ("seeds",))
  seeds = NamedSharding(mesh, P("seeds"))

  def local_chunk(states, t0):
    body = lambda st, t: jax.vmap(agent.step, in_axes=(0, None))(st, t)
    states, metrics = jax.lax.scan(body, states, t0 + jp.arange(chunk_steps))
    return states, reduce_chunk(metrics)

  def local_evaluate(states, key):
    return jax.vmap(agent.evaluate, in_axes=(0, 0, None))(
        states.low.params, states.middle.params, key)

  shard = lambda f, in_specs: jax.shard_map(f, mesh=mesh, in_specs=in_specs,
                                             out_specs=P("seeds"), check_vma=False)

  def init(key):
    return jax.vmap(agent.init)(jax.random.split(key, num_seeds))

  jit = functools.partial(jax.jit, compiler_options=compiler_options)
  return Trainer(
      agent=agent, num_seeds=num_seeds, chunk_steps=chunk_steps, mesh=mesh,
      init=jit(init, out_shardings=seeds),
      chunk=jit(shard(local_chunk, (P("seeds"), P())), donate_argnums=0),
      evaluate=jit(shard(local_evaluate, (P("seeds"), P()))))
