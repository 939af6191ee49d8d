"""How g_expl_mode is chosen: one interface, three choosers; the only thing methods differ in.
By ``AgentConfig.switch``:

    "none"         HIRO: always TD3, no starting mode (``Fixed``)
    "top"          ours: the Top PPO picks a mode per Top horizon (top.py); RANDOM in the
                   starting mode (``TopState``)
    "homeostasis"  Ref:Uniform / Ref:PPO: the informed trigger at Middle decisions
                   (switch.py); the explore mode in the starting mode (``TriggerState``)

A chooser (the ``ModeChooser`` protocol: ``FixedChooser``, ``TopChooser``, ``TriggerChooser``)
owns its state (``SeedState.chooser``: ``Fixed``, ``TopState`` or the trigger's
``TriggerState``, per env) and four pure methods:

    init(keys, obs, middle_params) -> (state, mode)              the first segments' modes (E,)
    accumulate(state, reward, success) -> state                  every env step (R_m, Done_m)
    decide(state, mode, decision, keys, hp) -> (state, mode, metrics)  at a Middle decision
    update(state, t, live, s_e, hp) -> (state, metrics)          its learner, on its own clock

``hp`` is the lane's ``lanes.Numbers`` (the Top's alpha, S_O and its two switches, the
trigger's rho): numbers read at run time, so variants of one program differ in them.

``keys`` are the agent's named keys (``agent.InitKeys`` / ``agent.StepKeys``): the Top uses
``top`` and ``horizon``, the trigger ``switch``. The starting mode runs after warm-up until
``live_from``; then the chooser's own choices start.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Protocol, Union

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import hierarchy, ppo, td3
from nonmono_jax.core import metrics as metrics_lib
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.gates import gated
from nonmono_jax.core.lanes import Numbers
from nonmono_jax.core.switch import InformedSwitch, TriggerState, make_informed_switch
from nonmono_jax.core.top import Horizon, Top, make_top

N_MODES = len(hierarchy.MODES)


@struct.dataclass
class Decision:
  """What a Middle decision at the end of step ``t`` sees (per env where batched)."""

  t: jax.Array  # the global step that just ran (unbatched)
  episode_end: jax.Array  # the episode ended with this step (the envs are reset)
  obs: jax.Array  # (E, obs) s where the next segment starts
  s_c: jax.Array  # (E, obs) the finished segment's last state
  reward: jax.Array  # (E,) its Middle reward R_M
  middle: td3.TD3Params  # the Middle TD3 (the trigger's V)


@struct.dataclass
class Fixed:
  """HIRO's chooser has no state."""

  def learner_params(self) -> dict:
    return {}


@struct.dataclass
class TopState:
  """The Top PPO, its rollout (E, rollout_length) and every env's current horizon (E,)."""

  learner: ppo.PPOState
  rollout: ppo.Rollout
  horizon: Horizon

  def learner_params(self) -> dict:
    return {"top": self.learner.params}


ChooserState = Union[Fixed, TopState, TriggerState]  # what a seed's chooser holds (per env)


class ModeChooser(Protocol):
  """What a chooser is (module doc): its constants and four pure functions."""

  name: str  # "none", "top" or "homeostasis" (config.switch)
  starting_mode: int
  live_from: int  # warm-up + the starting mode: the first step of the chooser's own choices

  def init(self, keys, obs, middle_params) -> tuple[ChooserState, jax.Array]: ...
  def accumulate(self, state: ChooserState, reward, success) -> ChooserState: ...
  def decide(self, state: ChooserState, mode, decision: Decision, keys,
             hp: Numbers) -> tuple[ChooserState, jax.Array, dict]: ...
  def update(self, state: ChooserState, t, live, s_e, hp: Numbers
             ) -> tuple[ChooserState, dict]: ...


@dataclasses.dataclass(frozen=True)
class FixedChooser:
  """HIRO: TD3 goals always; no state, nothing to learn."""

  num_envs: int
  live_from: int
  name = "none"
  starting_mode = hierarchy.TD3

  def init(self, keys, obs, middle_params) -> tuple[Fixed, jax.Array]:
    return Fixed(), jp.full((self.num_envs,), hierarchy.TD3, jp.int32)

  def accumulate(self, state, reward, success):
    return state

  def decide(self, state, mode, decision: Decision, keys, hp: Numbers):
    return state, mode, {}

  def update(self, state, t, live, s_e, hp: Numbers):
    return state, {}


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class TopChooser:
  """Ours: m ~ pi_T(s, target) per Top horizon; Top PPO every ``top.train_every`` steps."""

  top: Top
  num_envs: int
  live_from: int  # warm-up + top.starting_steps
  name = "top"
  starting_mode = hierarchy.RANDOM

  def _start(self, params, obs, key, forced) -> Horizon:
    keys = jax.random.split(key, self.num_envs)
    return jax.vmap(self.top.start, in_axes=(None, 0, 0, None))(params, obs, keys, forced)

  def init(self, keys, obs, middle_params) -> tuple[TopState, jax.Array]:
    learner = self.top.ppo.init(keys.top)
    horizon = self._start(learner.params, obs, keys.horizon, self.live_from > 0)
    rollout = jax.vmap(lambda _: self.top.init_rollout())(jp.arange(self.num_envs))
    return TopState(learner=learner, rollout=rollout, horizon=horizon), horizon.mode

  def accumulate(self, state: TopState, reward, success) -> TopState:
    return state.replace(horizon=jax.vmap(self.top.accumulate)(state.horizon, reward, success))

  def mode_probs(self, params, obs) -> jax.Array:
    """pi_T(m | s_0, target) per mode, averaged over the envs."""
    log_prob = lambda x, a: self.top.ppo.log_prob(params, x, a, None)
    per_env = lambda x: jp.exp(jax.vmap(lambda a: log_prob(x, a))(jp.arange(N_MODES)))
    return jax.vmap(per_env)(obs).mean(0)

  def decide(self, state: TopState, mode, d: Decision, keys, hp: Numbers):
    """At a horizon's end: the Top transition, and the Top picks the next g_expl_mode."""
    H, top = self.top.config.horizon, self.top

    def end_horizon(operand):
      state, _ = operand
      tr, m = jax.vmap(top.close, in_axes=(0, None, None, None))(
          state.horizon, d.t + 1 - H < self.live_from, d.episode_end, hp.top)
      slot = (d.t // H) % top.config.rollout_length
      rollout = jax.tree.map(lambda r, x: r.at[:, slot].set(x), state.rollout, tr)
      horizon = self._start(state.learner.params, d.obs, keys.horizon,
                            d.t + 1 < self.live_from)
      probs = self.mode_probs(state.learner.params, horizon.obs)
      m = {k: v.mean() for k, v in m.items()}
      m.update({f"p_{name}": probs[j] for j, name in enumerate(hierarchy.MODES)})
      return (state.replace(rollout=rollout, horizon=horizon), horizon.mode), m

    horizon_end = d.t % H == H - 1
    (state, mode), m = gated(horizon_end, end_horizon, (state, mode))
    return state, mode, metrics_lib.level("horizon", m, horizon_end)

  def update(self, state: TopState, t, live, s_e, hp: Numbers):
    every = self.top.config.train_every
    ran = live & (t % every == every - 1)

    def train(state):
      learner, m = self.top.update(state.learner, state.rollout, s_e, hp.top)
      return state.replace(learner=learner), m

    state, m = gated(ran, train, state)
    return state, metrics_lib.level("top", m, ran)


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


def make_chooser(config: AgentConfig, obs_size: int, target, value: Callable) -> ModeChooser:
  """The chooser of ``config.switch`` ("none", "top" or "homeostasis"); ``value`` the
  Middle's V for the trigger."""
  E, starting = config.num_envs, config.warmup_steps + config.top.starting_steps
  if config.switch == "top":
    top = make_top(obs_size, target, config.top, config.returns_cross_episodes)
    return TopChooser(top=top, num_envs=E, live_from=starting)
  if config.switch == "homeostasis":
    switch = make_informed_switch(config.homeostasis, config.explore_mode_index, config.c)
    return TriggerChooser(switch=switch, value=value, num_envs=E, live_from=starting,
                          starting_mode=config.explore_mode_index)
  return FixedChooser(num_envs=E, live_from=config.warmup_steps)
