"""The jitted core of training: chunks of env steps for every seed at once.

    trainer = make_trainer(env, agent_config, num_seeds=4, chunk_steps=2000)
    states = trainer.init(key)                      # one SeedState per seed (vmapped)
    for t0 in range(0, total, trainer.chunk_steps):  # Python: progress, logs, checkpoints
      states, metrics = trainer.chunk(states, t0)   # lax.scan over steps, vmap over seeds
    s_e, distance = trainer.evaluate(states, key)   # per seed

Inside a chunk the global step ``t`` is the scan's input and is not batched over seeds, so
every horizon gate in ``agent.step`` stays a real branch (SPEC section 6). ``metrics`` are the
per-seed means over the chunk of the agent's per-step metrics.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp

from nonmono_jax import agent as agent_lib
from nonmono_jax import evaluate as evaluate_lib


@dataclasses.dataclass(frozen=True)
class Trainer:
  agent: agent_lib.Agent
  num_seeds: int
  chunk_steps: int
  init: Callable
  chunk: Callable
  evaluate: Callable


def make_trainer(env, config: agent_lib.AgentConfig, num_seeds: int, chunk_steps: int,
                 eval_episodes: int = 50) -> Trainer:
  """Jitted ``init(key)``, ``chunk(states, t0)`` and ``evaluate(states, key)``."""
  for name, v in (("num_seeds", num_seeds), ("chunk_steps", chunk_steps),
                  ("eval_episodes", eval_episodes)):
    if v < 1:
      raise ValueError(f"{name} must be >= 1, got {v}")
  agent = agent_lib.make_agent(env, config)

  def init(key):
    return jax.vmap(agent.init)(jax.random.split(key, num_seeds))

  def chunk(states, t0):
    body = lambda st, t: jax.vmap(agent.step, in_axes=(0, None))(st, t)
    states, metrics = jax.lax.scan(body, states, t0 + jp.arange(chunk_steps))
    return states, jax.tree.map(lambda m: m.mean(axis=0), metrics)

  def evaluate(states, key):
    return jax.vmap(lambda lo, mi: evaluate_lib.success_rate(agent, env, lo, mi, key,
                                                             eval_episodes))(
        states.low.params, states.middle.params)

  return Trainer(agent=agent, num_seeds=num_seeds, chunk_steps=chunk_steps,
                 init=jax.jit(init), chunk=jax.jit(chunk), evaluate=jax.jit(evaluate))
