"""The informed mode switch of Ref:Uniform and Ref:PPO (Pislar et al.'s XU/XI-intra(100, informed)).

Two modes at the Middle: exploit (TD3 goals) and explore (uniform random or Middle PPO goals).
Per env and env step, with V(s) = Q1_M(s, target, pi_M(s, target)) from the Middle TD3:

    window  <- the last k + 1 values V(s_{t-k}) .. V(s_t) and the k rewards between them
    x_t     =  D(t-k, t) = |V(s_{t-k}) - sum_i gamma^i r_{t-k+i} - gamma^k V(s_t)|
    homeostasis(x_t) -> switch ~ Bernoulli(min(1, rho xplus / xplusbar))   (once k steps in)
    exploit --switch--> explore for exactly ``explore_steps`` (100) env steps, then exploit
    each episode starts in explore mode (X), for ``explore_steps`` steps

The mode in effect during a step is the one before that step's switch decision; a Middle goal
picked at a segment's end uses the mode of the next step.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax import hierarchy, homeostasis


@struct.dataclass
class TriggerState:
  """One env's trigger: homeostasis, the value window and the explore steps left."""

  homeostasis: homeostasis.HomeostasisState
  values: jax.Array  # (k + 1,) V(s_{t-k}) .. V(s_t)
  rewards: jax.Array  # (k,) r_{t-k} .. r_{t-1}
  explore_left: jax.Array  # int32: steps left in the current explore period (0: exploit)


@dataclasses.dataclass(frozen=True)
class InformedSwitch:
  config: homeostasis.HomeostasisConfig
  explore_mode: int
  init: Callable[[jax.Array], TriggerState]
  reset: Callable[[TriggerState, jax.Array], TriggerState]
  mode: Callable[[TriggerState], jax.Array]
  step: Callable[..., tuple[TriggerState, jax.Array]]


def make_informed_switch(config: homeostasis.HomeostasisConfig,
                         explore_mode: int) -> InformedSwitch:
  k = config.k

  def reset(state: TriggerState, v0):
    """An episode starts: explore for ``explore_steps``; the window restarts at V(s_0)."""
    return state.replace(values=jp.full((k + 1,), v0), rewards=jp.zeros((k,)),
                         explore_left=jp.asarray(config.explore_steps, jp.int32))

  def init(v0):
    return reset(TriggerState(homeostasis=homeostasis.init(), values=jp.zeros((k + 1,)),
                              rewards=jp.zeros((k,)), explore_left=jp.zeros((), jp.int32)), v0)

  def mode(state: TriggerState):
    return jp.where(state.explore_left > 0, explore_mode, hierarchy.TD3).astype(jp.int32)

  def step(state: TriggerState, v_next, reward, key, window_full):
    """After an env step: slide the window and maybe switch to explore.

    ``window_full`` (unbatched: at least k steps into the episode) gates homeostasis.
    Returns the new state and whether it switched.
    """
    values = jp.concatenate([state.values[1:], v_next[None]])
    rewards = jp.concatenate([state.rewards[1:], reward[None]])
    exploiting = state.explore_left == 0
    left = jp.maximum(state.explore_left - 1, 0)
    state = state.replace(values=values, rewards=rewards, explore_left=left)

    def trigger(state):
      x = homeostasis.value_promise_discrepancy(values[0], rewards, values[k], config.gamma)
      h, switch = homeostasis.update(state.homeostasis, x, key, config.rho)
      switch = switch & exploiting
      left = jp.where(switch, config.explore_steps, state.explore_left).astype(jp.int32)
      return state.replace(homeostasis=h, explore_left=left), switch

    return jax.lax.cond(window_full, trigger, lambda s: (s, jp.zeros((), bool)), state)

  return InformedSwitch(config=config, explore_mode=explore_mode, init=init, reset=reset,
                        mode=mode, step=step)
