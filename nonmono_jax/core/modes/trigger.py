"""The Ref methods' chooser (switch "homeostasis"): the informed mode switch of Ref:Uniform and
Ref:PPO, as the paper's code runs it. Its options are ``config.HomeostasisConfig``
(``AgentConfig.homeostasis``) and ``AgentConfig.explore_mode``; its starting phase is the Top's
starting mode (``top.starting_steps``).

Pislar et al.'s XU/XI-intra(100, informed, p*, X) at the Middle: two modes, exploit (TD3
goals) and explore (uniform random or Middle PPO goals). The paper's Ref code decides at
Middle decisions (every c env steps), per env:

    starting phase (after warm-up, top.starting_steps env steps): explore      (its "X")
    exploit period: the window holds V(s) at the last k + 1 Middle decisions and the k
      Middle rewards R_M between them, V(s) = min(Q1', Q2')(s, target, pi'_M(s, target))
      (the twin *target* critics at the target actor);
      once it holds k segments, at every Middle decision:
        x = D = |V(s_{j-k}) - sum_i gamma^i R_M,{j-k+i} - gamma^k V(s_j)|  (j counts decisions)
        homeostasis(x) -> switch ~ Bernoulli(min(1, rho xplus / xplusbar))
        switch: explore for explore_steps / c Middle decisions (100 env steps)
    after an explore period: a new exploit period, with a fresh window and (``reset_stats``)
      fresh homeostasis statistics

With ``cadence="code"`` (the paper's code's counter) the periods differ, the window not:

    after the starting phase (``restart``): explore for k - 1 more Middle decisions, a check
    switch: explore for k Middle decisions (300 env steps at k = 30, c = 10), then a check
    no switch: exploit for one segment, then a check
    the window slides at every decision, explore ones included (the first check after the
      starting phase sees k - 1 segments and restart's padding: V repeated, reward 0);
      fresh statistics at the check that ends an explore period (``reset_stats``)

Deliberate differences from the paper's code (docs/fidelity.md): explore periods last
the stated 100 steps (its counter bug makes them about 300; ``cadence="code"`` keeps it);
homeostasis divides by the standard deviation (it divides by the variance squared); after
its first check it keeps checking every decision but with a window of one segment and no
reward (its accumulators are reset and never refilled): here the window slides over the last
k segments; D is in the Middle critic's units (0.1-scaled segment rewards; its code
subtracts raw sums); tau = min(n, 100 / rho) with n the checks since the reset (its code
passes 30 every time).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import hierarchy, homeostasis
from nonmono_jax.core import metrics as metrics_lib
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import Numbers
from nonmono_jax.core.modes import Decision


@struct.dataclass
class TriggerState:
  """One env's trigger: homeostasis, the value window and the explore decisions left."""

  homeostasis: homeostasis.HomeostasisState
  values: jax.Array  # (k + 1,) V at the last k + 1 Middle decisions of the exploit period
  rewards: jax.Array  # (k,) R_M of the k segments between them
  filled: jax.Array  # int32: segments in the window (at most k)
  explore_left: jax.Array  # int32: Middle decisions left in the explore period (0: exploit)

  def learner_params(self) -> dict:
    return {}  # the trigger learns nothing: V is the Middle TD3's


@dataclasses.dataclass(frozen=True)
class InformedSwitch:
  config: homeostasis.HomeostasisConfig
  explore_mode: int
  init: Callable[[jax.Array], TriggerState]
  restart: Callable[[TriggerState, jax.Array], TriggerState]
  mode: Callable[[TriggerState], jax.Array]
  decide: Callable[..., tuple[TriggerState, jax.Array]]


def make_informed_switch(config: homeostasis.HomeostasisConfig, explore_mode: int,
                         c: int) -> InformedSwitch:
  """The trigger of Middle decisions every ``c`` env steps (``explore_steps`` a multiple of c)."""
  k = config.k
  explore_decisions = config.explore_steps // c
  code = config.cadence == "code"
  restart_left = k - 1 if code else 0  # the code's counter: k - 1 explore decisions to go

  def restart(state: TriggerState, v):
    """A new exploit period from a state of value v: fresh window (and statistics); with
    ``cadence="code"`` k - 1 explore decisions first (the end of the starting phase)."""
    h = homeostasis.init() if config.reset_stats else state.homeostasis
    return state.replace(homeostasis=h, values=jp.full((k + 1,), v), rewards=jp.zeros((k,)),
                         filled=jp.zeros((), jp.int32),
                         explore_left=jp.full((), restart_left, jp.int32))

  def init(v0):
    zero = jp.zeros((), jp.int32)
    return restart(TriggerState(homeostasis=homeostasis.init(), values=jp.zeros((k + 1,)),
                                rewards=jp.zeros((k,)), filled=zero, explore_left=zero), v0)

  def mode(state: TriggerState):
    return jp.where(state.explore_left > 0, explore_mode, hierarchy.TD3).astype(jp.int32)

  def exploit(state: TriggerState, v, reward, key, rho):
    """Slide the window by one segment; once it is full, homeostasis may switch."""
    values = jp.concatenate([state.values[1:], v[None]])
    rewards = jp.concatenate([state.rewards[1:], reward[None]])
    filled = jp.minimum(state.filled + 1, k)
    x = homeostasis.value_promise_discrepancy(values[0], rewards, values[k], config.gamma)
    h, switch = homeostasis.update(state.homeostasis, x, key, rho)
    check = filled >= k
    h = jax.tree.map(lambda new, old: jp.where(check, new, old), h, state.homeostasis)
    switch = switch & check
    left = jp.where(switch, explore_decisions, 0).astype(jp.int32)
    return state.replace(homeostasis=h, values=values, rewards=rewards, filled=filled,
                         explore_left=left), switch

  def decide(state: TriggerState, v, reward, key, rho=config.rho):
    """At a Middle decision: V(s) of the new segment's start, R_M of the finished segment;
    ``rho`` the target rate (a lane's number: ``homeostasis.rho``).

    Returns the new state (``mode`` gives the next segment's mode) and whether it switched
    to explore.
    """
    left = state.explore_left - 1
    explored = jax.tree.map(lambda a, b: jp.where(left == 0, a, b), restart(state, v),
                            state.replace(explore_left=jp.maximum(left, 0)))
    exploited, switch = exploit(state, v, reward, key, rho)
    exploring = state.explore_left > 0
    new = jax.tree.map(lambda a, b: jp.where(exploring, a, b), explored, exploited)
    return new, switch & ~exploring

  def code_check(state: TriggerState, x, key, rho):
    """The code's cadence: homeostasis checks x unless an explore run goes on (fresh
    statistics at the check that ends one)."""
    fresh = homeostasis.init() if config.reset_stats else state.homeostasis
    ending = state.explore_left == 1
    h = jax.tree.map(lambda a, b: jp.where(ending, a, b), fresh, state.homeostasis)
    h, switch = homeostasis.update(h, x, key, rho)
    check = state.explore_left <= 1
    h = jax.tree.map(lambda new, old: jp.where(check, new, old), h, state.homeostasis)
    return h, switch & check

  def decide_code(state: TriggerState, v, reward, key, rho=config.rho):
    """``decide`` with ``cadence="code"``: the window slides at every decision, explore ones
    included; a switch explores for k decisions."""
    values = jp.concatenate([state.values[1:], v[None]])
    rewards = jp.concatenate([state.rewards[1:], reward[None]])
    x = homeostasis.value_promise_discrepancy(values[0], rewards, values[k], config.gamma)
    h, switch = code_check(state, x, key, rho)
    left = jp.where(switch, k, jp.maximum(state.explore_left - 1, 0)).astype(jp.int32)
    return state.replace(homeostasis=h, values=values, rewards=rewards,
                         filled=jp.minimum(state.filled + 1, k), explore_left=left), switch

  return InformedSwitch(config=config, explore_mode=explore_mode, init=init, restart=restart,
                        mode=mode, decide=decide_code if code else decide)


# --- the chooser -------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class TriggerChooser:
  """Ref: the informed switch decides at every Middle decision; ``value(middle_params, obs)``
  is the Middle's V (the trigger's signal)."""

  switch: InformedSwitch
  value: Callable[..., jax.Array]
  num_envs: int
  live_from: int  # warm-up + top.starting_steps (the explore mode until then)
  starting_mode: int  # the explore mode
  name = "homeostasis"

  def init(self, keys, obs, middle_params) -> tuple[TriggerState, jax.Array]:
    trigger = jax.vmap(self.switch.init)(self.value(middle_params, obs))
    first = self.starting_mode if self.live_from > 0 else hierarchy.TD3
    return trigger, jp.full((self.num_envs,), first, jp.int32)

  def accumulate(self, state, reward, success):
    return state

  def decide(self, trigger: TriggerState, mode, d: Decision, keys, hp: Numbers):
    """The trigger decides the next segment's mode (explore in the starting mode)."""
    v, E, switch = self.value(d.middle, d.s_c), self.num_envs, self.switch

    def starting(trigger):
      return jax.vmap(switch.restart)(trigger, v), jp.zeros((E,), bool)

    def deciding(trigger):
      return jax.vmap(switch.decide, in_axes=(0, 0, 0, 0, None))(
          trigger, v, d.reward, jax.random.split(keys.switch, E), hp.homeostasis.rho)

    # The window of the first exploit period starts at s_{live_from}.
    trigger, switched = jax.lax.cond(d.t + 1 <= self.live_from, starting, deciding, trigger)
    mode = jp.where(d.t + 1 < self.live_from, self.starting_mode,
                    jax.vmap(switch.mode)(trigger))
    return (trigger, mode.astype(jp.int32),
            {"switch/switches": metrics_lib.Metric.sum(switched.sum().astype(jp.float32))})

  def update(self, state, t, live, s_e, hp: Numbers):
    return state, {}


def explore_index(config: AgentConfig) -> int:
  """The mode index of ``config.explore_mode``: PPO or RANDOM."""
  return hierarchy.PPO if config.explore_mode == "ppo" else hierarchy.RANDOM


def make(config: AgentConfig, obs_size: int, target, value: Callable) -> TriggerChooser:
  mode = explore_index(config)
  return TriggerChooser(switch=make_informed_switch(config.homeostasis, mode, config.c),
                        value=value, num_envs=config.num_envs,
                        live_from=config.warmup_steps + config.top.starting_steps,
                        starting_mode=mode)
