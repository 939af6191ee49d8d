"""How g_expl_mode is chosen: one interface, three choosers; the only thing methods differ in.
By ``AgentConfig.switch``:

    "none"         HIRO: always TD3, no starting mode (``Fixed``)
    "top"          ours: the Top PPO picks a mode per Top horizon (top.py); RANDOM in the
                   starting mode (``TopState``)
    "homeostasis"  Ref:Uniform / Ref:PPO: the informed trigger at Middle decisions
                   (switch.py); the explore mode in the starting mode (``TriggerState``)

A chooser owns its state (``SeedState.chooser``: ``Fixed``, ``TopState`` or the trigger's
``TriggerState``, per env) and four pure functions:

    init(keys, obs, middle_params) -> (state, mode)              the first segments' modes (E,)
    accumulate(state, reward, success) -> state                  every env step (R_m, Done_m)
    decide(state, mode, decision, keys, hp) -> (state, mode, metrics)  at a Middle decision
    update(state, t, live, s_e, hp) -> (state, metrics)          its learner, on its own clock

``hp`` is the lane's ``numbers.Numbers`` (the Top's alpha, S_O and its two switches, the
trigger's rho): numbers read at run time, so variants of one program differ in them.

``keys`` are the agent's named keys (``agent.InitKeys`` / ``agent.StepKeys``): the Top uses
``top`` and ``horizon``, the trigger ``switch``. The starting mode runs after warm-up until
``live_from``; then the chooser's own choices start.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Union

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import hierarchy, ppo, td3
from nonmono_jax.core import metrics as metrics_lib
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.gates import gated
from nonmono_jax.core.switch import TriggerState, make_informed_switch
from nonmono_jax.core.top import Horizon, make_top

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


@dataclasses.dataclass(frozen=True)
class ModeChooser:
  name: str  # "none", "top" or "homeostasis" (config.switch)
  starting_mode: int
  live_from: int  # warm-up + the starting mode: the first step of the chooser's own choices
  init: Callable[..., tuple[ChooserState, jax.Array]]
  accumulate: Callable[..., ChooserState]
  decide: Callable[..., tuple[ChooserState, jax.Array, dict]]
  update: Callable[..., tuple[ChooserState, dict]]


def _unchanged_accumulate(state, reward, success):
  return state


def _no_update(state, t, live, s_e, hp):
  return state, {}


def make_fixed(config: AgentConfig, num_envs: int) -> ModeChooser:
  """HIRO: TD3 goals always."""

  def init(keys, obs, middle_params):
    return Fixed(), jp.full((num_envs,), hierarchy.TD3, jp.int32)

  def decide(state, mode, decision, keys, hp):
    return state, mode, {}

  return ModeChooser(name="none", starting_mode=hierarchy.TD3, live_from=config.warmup_steps,
                     init=init, accumulate=_unchanged_accumulate, decide=decide,
                     update=_no_update)


def make_top_chooser(config: AgentConfig, obs_size: int, target, num_envs: int) -> ModeChooser:
  """Ours: m ~ pi_T(s, target) per Top horizon; Top PPO every ``top.train_every`` steps."""
  cfg, E = config.top, num_envs
  top = make_top(obs_size, target, cfg, config.returns_cross_episodes)
  live_from = config.warmup_steps + cfg.starting_steps
  start = jax.vmap(top.start, in_axes=(None, 0, 0, None))

  def init(keys, obs, middle_params):
    learner = top.ppo.init(keys.top)
    horizon = start(learner.params, obs, jax.random.split(keys.horizon, E), live_from > 0)
    rollout = jax.vmap(lambda _: top.init_rollout())(jp.arange(E))
    return TopState(learner=learner, rollout=rollout, horizon=horizon), horizon.mode

  def accumulate(state, reward, success):
    return state.replace(horizon=jax.vmap(top.accumulate)(state.horizon, reward, success))

  def mode_probs(params, obs):
    """pi_T(m | s_0, target) per mode, averaged over the envs."""
    logp = lambda x: jax.vmap(lambda a: top.ppo.log_prob(params, x, a, None))(jp.arange(N_MODES))
    return jax.vmap(lambda x: jp.exp(logp(x)))(obs).mean(0)

  def decide(state, mode, d: Decision, keys, hp):
    """At a horizon's end: the Top transition, and the Top picks the next g_expl_mode."""
    H = cfg.horizon
    horizon_end = d.t % H == H - 1

    def end_horizon(operand):
      state, _ = operand
      tr, m = jax.vmap(top.close, in_axes=(0, None, None, None))(
          state.horizon, d.t + 1 - H < live_from, d.episode_end, hp.top)
      slot = (d.t // H) % cfg.rollout_length
      rollout = jax.tree.map(lambda r, x: r.at[:, slot].set(x), state.rollout, tr)
      horizon = start(state.learner.params, d.obs, jax.random.split(keys.horizon, E),
                      d.t + 1 < live_from)
      probs = mode_probs(state.learner.params, horizon.obs)
      m = {k: v.mean() for k, v in m.items()}
      m.update({f"p_{name}": probs[j] for j, name in enumerate(hierarchy.MODES)})
      return (state.replace(rollout=rollout, horizon=horizon), horizon.mode), m

    (state, mode), m = gated(horizon_end, end_horizon, (state, mode))
    return state, mode, metrics_lib.level("horizon", m, horizon_end)

  def update(state, t, live, s_e, hp):
    every = cfg.train_every
    ran = live & (t % every == every - 1)

    def train(state):
      learner, m = top.update(state.learner, state.rollout, s_e, hp.top)
      return state.replace(learner=learner), m

    state, m = gated(ran, train, state)
    return state, metrics_lib.level("top", m, ran)

  return ModeChooser(name="top", starting_mode=hierarchy.RANDOM, live_from=live_from,
                     init=init, accumulate=accumulate, decide=decide, update=update)


def make_trigger_chooser(config: AgentConfig, value: Callable, num_envs: int) -> ModeChooser:
  """Ref: the informed switch decides every Middle decision; ``value(middle_params, obs)``."""
  E, explore = num_envs, config.explore_mode_index
  switch = make_informed_switch(config.homeostasis, explore, config.c)
  live_from = config.warmup_steps + config.top.starting_steps

  def init(keys, obs, middle_params):
    trigger = jax.vmap(switch.init)(value(middle_params, obs))
    return trigger, jp.full((E,), explore if live_from > 0 else hierarchy.TD3, jp.int32)

  def decide(trigger, mode, d: Decision, keys, hp):
    """The trigger decides the next segment's mode (explore in the starting mode)."""
    v = value(d.middle, d.s_c)

    def starting(trigger):
      return jax.vmap(switch.restart)(trigger, v), jp.zeros((E,), bool)

    def deciding(trigger):
      return jax.vmap(switch.decide, in_axes=(0, 0, 0, 0, None))(
          trigger, v, d.reward, jax.random.split(keys.switch, E), hp.homeostasis.rho)

    # The window of the first exploit period starts at s_{live_from}.
    trigger, switched = jax.lax.cond(d.t + 1 <= live_from, starting, deciding, trigger)
    mode = jp.where(d.t + 1 < live_from, explore, jax.vmap(switch.mode)(trigger))
    return (trigger, mode.astype(jp.int32),
            {"switch/switches": metrics_lib.Metric.sum(switched.sum().astype(jp.float32))})

  return ModeChooser(name="homeostasis", starting_mode=explore, live_from=live_from,
                     init=init, accumulate=_unchanged_accumulate, decide=decide,
                     update=_no_update)


def make_chooser(config: AgentConfig, obs_size: int, target, value: Callable) -> ModeChooser:
  """The chooser of ``config.switch`` ("none", "top" or "homeostasis")."""
  if config.switch == "top":
    return make_top_chooser(config, obs_size, target, config.num_envs)
  if config.switch == "homeostasis":
    return make_trigger_chooser(config, value, config.num_envs)
  return make_fixed(config, config.num_envs)
