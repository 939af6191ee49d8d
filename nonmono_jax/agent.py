"""One env step of the whole agent for one seed: the paper's Algorithm 1 (vmap seeds, scan time).

A seed runs ``num_envs`` envs (1 in the paper) that share its learners and buffers. Per step t:

    Low:     a = clip(pi_L(s, g) + noise) (uniform in warm-up) -> env.step -> s', R, success
             Low buffer <- (s, g, a, r_L, s', g');  g <- g' = s[:3] + g - s'[:3]
    Top:     R_m += R, Done_m += success, Count_m += 1                           (top.py)
    episode end (every episode_length steps, all envs at once): reset
    every c steps (Middle horizon, a Middle decision):
      Middle TD3 buffer + Middle PPO rollout <- (s_0, g, 0.1 sum R, s_c, success)  (middle.py)
      every top.horizon steps (ours): Top transition; g_expl_mode ~ pi_T(s, target)
      Ref: V'(s_c) -> value promise discrepancy -> homeostasis -> explore?        (switch.py)
      next goal from the sub-policy of g_expl_mode (TD3 / PPO / RANDOM)
    updates (after warm-up): Low TD3 every step, Middle TD3 every c, Middle PPO every 30,
      Top PPO every 400; evaluation of Middle TD3 + Low TD3 every 10K steps -> S_E

Methods differ only in ``config.switch``: "none" (HIRO: always TD3, Gaussian goal noise),
"top" (ours) or "homeostasis" (Ref:Uniform / Ref:PPO). Every gate is a function of the global
step ``t``, which is not batched over seeds, so each stays a real ``lax.cond`` under ``vmap``
(SPEC section 6); only per-env data (modes, explore periods) is batched.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax import buffers, hierarchy, ppo, td3
from nonmono_jax import evaluate as evaluate_lib
from nonmono_jax.config import AgentConfig
from nonmono_jax.low import Low, make_low
from nonmono_jax.middle import Middle, Segment, make_middle
from nonmono_jax.switch import InformedSwitch, TriggerState, make_informed_switch
from nonmono_jax.top import Horizon, Top, make_top

N_MODES = len(hierarchy.MODES)


@struct.dataclass
class SeedState:
  """Everything one seed owns; per-env fields have a leading ``num_envs`` axis."""

  env: Any  # envs.MazeState, (E,)
  low: td3.TD3State
  middle: td3.TD3State
  middle_ppo: ppo.PPOState | None
  top: ppo.PPOState | None
  low_buffer: buffers.ReplayBuffer
  middle_buffer: buffers.ReplayBuffer
  middle_rollout: ppo.Rollout | None  # (E, middle_ppo_every / c)
  top_rollout: ppo.Rollout | None  # (E, top.train_every / top.horizon)
  goal: jax.Array  # (E, 3)
  segment: Segment  # (E,)
  mode: jax.Array  # (E,) int32 g_expl_mode in effect
  horizon: Horizon | None  # (E,) the current Top horizon (ours)
  trigger: TriggerState | None  # (E,) the informed switch (Ref:*)
  mode_steps: jax.Array  # (3,) int32 env steps run in each mode after warm-up
  mode_decisions: jax.Array  # (3,) int32 Middle decisions in each mode after warm-up
  mode_steps_after_start: jax.Array  # (3,) the same after the starting mode
  mode_decisions_after_start: jax.Array  # (3,)
  s_e: jax.Array  # the latest evaluation success rate S_E
  eval_distance: jax.Array  # and its mean final distance to the target
  eval_return: jax.Array  # and its mean episode return
  key: jax.Array


@dataclasses.dataclass(frozen=True)
class Agent:
  """The agent's pure functions: ``init(key) -> SeedState`` and ``step(state, t)``."""

  config: AgentConfig
  env: Any
  low: Low
  middle: Middle
  top: Top | None
  switch: InformedSwitch | None
  init: Callable[[jax.Array], SeedState]
  step: Callable[[SeedState, jax.Array], tuple[SeedState, dict]]
  evaluate: Callable[..., tuple]  # (low params, middle params, key) -> S_E, distance, return


def _gated(pred, fn, state):
  """``lax.cond(pred, fn, skip)`` where skip returns ``state`` and zero metrics."""
  _, shapes = jax.eval_shape(fn, state)

  def skip(s):
    return s, jax.tree.map(lambda x: jp.zeros(x.shape, x.dtype), shapes)

  return jax.lax.cond(pred, fn, skip, state)


def _write_slot(rollout, j, steps):
  """Rollout (E, N, ...) with slot j of every env set to ``steps`` (E, ...)."""
  return jax.tree.map(lambda r, x: r.at[:, j].set(x), rollout, steps)


def _prefixed(prefix, metrics, ran):
  return {**{f"{prefix}/{k}": v for k, v in metrics.items()},
          f"{prefix}/updated": jp.asarray(ran, jp.float32)}


def make_agent(env, config: AgentConfig = AgentConfig()) -> Agent:
  """Build the agent for an env of ``envs`` (obs[:3] is the robot's xyz)."""
  config.check_env(env)
  E, c, L = config.num_envs, config.c, env.episode_length
  obs_size, act_size = env.observation_size, env.action_size
  target = jp.asarray(env.target, jp.float32)
  has_top, informed = config.switch == "top", config.switch == "homeostasis"
  has_ppo = config.uses_middle_ppo
  top_cfg = config.top
  # After warm-up, the starting mode (ours: the Top forced to RANDOM; Ref: explore) runs
  # until live_from; then the Top's (or the trigger's) own choices start.
  # HIRO has no starting mode (always TD3).
  live_from = config.warmup_steps + (top_cfg.starting_steps if has_top or informed else 0)
  starting_mode = (hierarchy.RANDOM if has_top else
                   config.explore_mode_index if informed else hierarchy.TD3)

  low = make_low(obs_size, act_size, env.action_limit, config.low, config.low_updates)
  middle = make_middle(obs_size, act_size, target, config, low.td3.act)
  top = make_top(obs_size, target, top_cfg) if has_top else None
  switch = (make_informed_switch(config.homeostasis, config.explore_mode_index, c)
            if informed else None)
  evaluate = evaluate_lib.make_evaluate(env, c, low.td3.act, middle.td3.act,
                                        config.eval_episodes, config.eval_target_networks)

  def value(middle_params, obs):
    """V(s) = min(Q1', Q2')(s, target, pi'_M(s, target)): the trigger's value (target nets)."""
    tgt = jp.broadcast_to(target, obs.shape[:-1] + target.shape)
    targets = middle_params.replace(actor=middle_params.target_actor)
    q = middle.td3.q_values(middle_params.target_critic, obs, tgt,
                            middle.td3.act(targets, obs, tgt))
    return q.min(axis=0)

  def goals(state, obs, mode, key, warm, t):
    ppo_params = state.middle_ppo.params if has_ppo else None
    return jax.vmap(middle.goal, in_axes=(None, None, 0, 0, 0, None, None))(
        state.middle.params, ppo_params, obs, mode, jax.random.split(key, E), warm, t)

  def new_segments(state, obs, key, warm, t):
    """The goals of new segments from ``obs`` (random where ``warm``)."""
    goal, ppo_action, log_prob = goals(state, obs, state.mode, key, warm, t)
    return state.replace(goal=goal, segment=jax.vmap(middle.new_segment)(
        obs, goal, ppo_action, log_prob))

  def count(state, live, after_start, field, field_after_start):
    """Add one to each env's current mode in ``field`` (and after the starting mode)."""
    n = jax.nn.one_hot(state.mode, N_MODES, dtype=jp.int32).sum(0)
    return state.replace(**{field: getattr(state, field) + n * live,
                            field_after_start: getattr(state, field_after_start)
                            + n * after_start}), n * live

  def init(key):
    ke, kl, km, kp, kt, kh, kg, key = jax.random.split(key, 8)
    zeros_modes = jp.zeros((N_MODES,), jp.int32)
    env_state = jax.vmap(env.reset)(jax.random.split(ke, E))
    obs = env_state.obs
    state = SeedState(
        env=env_state, low=low.td3.init(kl), middle=middle.td3.init(km),
        middle_ppo=middle.ppo.init(kp) if has_ppo else None,
        top=top.ppo.init(kt) if has_top else None,
        low_buffer=low.init_buffer(), middle_buffer=middle.init_buffer(),
        middle_rollout=(jax.vmap(lambda _: middle.init_rollout())(jp.arange(E))
                        if has_ppo else None),
        top_rollout=jax.vmap(lambda _: top.init_rollout())(jp.arange(E)) if has_top else None,
        goal=jp.zeros((E, hierarchy.GOAL_SIZE)), segment=None,
        mode=jp.full((E,), starting_mode if live_from > 0 else hierarchy.TD3, jp.int32),
        horizon=None, trigger=None, mode_steps=zeros_modes, mode_decisions=zeros_modes,
        mode_steps_after_start=zeros_modes, mode_decisions_after_start=zeros_modes,
        s_e=jp.zeros(()),
        eval_distance=jp.zeros(()), eval_return=jp.zeros(()), key=key)
    if has_top:
      horizon = jax.vmap(top.start, in_axes=(None, 0, 0, None))(
          state.top.params, obs, jax.random.split(kh, E), live_from > 0)
      state = state.replace(horizon=horizon, mode=horizon.mode)
    if informed:
      state = state.replace(trigger=jax.vmap(switch.init)(value(state.middle.params, obs)))
    return new_segments(state, obs, kg, True, 0)

  def step(state: SeedState, t):
    """One env step of every env of the seed, at global step ``t`` (unbatched)."""
    key, ka, kr, ks, kh, kg, kl, km, kp, kt, kev, kc = jax.random.split(state.key, 12)
    warm = t < config.warmup_steps
    live = jp.logical_not(warm)
    i = t % c
    episode_end = (t + 1) % L == 0
    segment_end = i == c - 1
    horizon_end = has_top and (t % top_cfg.horizon == top_cfg.horizon - 1)

    # Low acts in every env; the env steps.
    s = state.env.obs
    a = jax.vmap(low.act, in_axes=(None, 0, 0, 0, None))(
        state.low.params, s, state.goal, jax.random.split(ka, E), warm)
    env_next = jax.vmap(env.step)(state.env, a)
    s_next, reward = env_next.obs, env_next.reward
    success = env_next.metrics["success"]
    low_tr = jax.vmap(low.transition)(s, state.goal, a, s_next)
    state, counted = count(state, live, t >= live_from, "mode_steps", "mode_steps_after_start")
    state = state.replace(
        env=env_next, low_buffer=buffers.add(state.low_buffer, low_tr), goal=low_tr.next_context,
        segment=jax.vmap(middle.record, in_axes=(0, None, 0, 0, 0, 0))(
            state.segment, i, a, s_next, reward, success),
        key=key)
    metrics = {"reward": reward.mean(), "success": success.mean(),
               "distance": env_next.metrics["distance"].mean(), "low/reward": low_tr.reward.mean(),
               **{f"count/{m}": counted[j] for j, m in enumerate(hierarchy.MODES)}}
    if has_top:
      state = state.replace(horizon=jax.vmap(top.accumulate)(state.horizon, reward, success))

    # An episode ends only at a segment's end (episode_length is a multiple of c), after
    # s_c is recorded, so the reset comes first and the next goal is chosen from the new state.
    def reset(state):
      return state.replace(env=jax.vmap(env.reset)(jax.random.split(kr, E)))

    state = jax.lax.cond(episode_end, reset, lambda s: s, state)

    def end_horizon(state):
      """Top transition of the finished horizon; the Top picks the next g_expl_mode."""
      start_t = t + 1 - top_cfg.horizon
      tr, m = jax.vmap(top.close, in_axes=(0, None, None))(
          state.horizon, start_t < live_from, episode_end)
      slot = (t // top_cfg.horizon) % top_cfg.rollout_length
      rollout = _write_slot(state.top_rollout, slot, tr)
      horizon = jax.vmap(top.start, in_axes=(None, 0, 0, None))(
          state.top.params, state.env.obs, jax.random.split(kh, E), t + 1 < live_from)
      probs = jax.vmap(lambda x: jp.exp(jax.vmap(
          lambda a: top.ppo.log_prob(state.top.params, x, a, None))(jp.arange(N_MODES))))(
              horizon.obs).mean(0)
      m = {k: v.mean() for k, v in m.items()}
      m.update({f"p_{name}": probs[j] for j, name in enumerate(hierarchy.MODES)})
      return state.replace(top_rollout=rollout, horizon=horizon, mode=horizon.mode), m

    def informed_switch(state, items):
      """Ref: the trigger decides the next segment's mode (explore in the starting mode)."""
      s_c = items["transition"].next_obs
      v = value(state.middle.params, s_c)

      def starting(trigger):
        return jax.vmap(switch.restart)(trigger, v), jp.zeros((E,), bool)

      def deciding(trigger):
        return jax.vmap(switch.decide)(trigger, v, items["transition"].reward,
                                       jax.random.split(ks, E))

      # The window of the first exploit period starts at s_{live_from}.
      trigger, switched = jax.lax.cond(t + 1 <= live_from, starting, deciding, state.trigger)
      mode = jp.where(t + 1 < live_from, starting_mode, jax.vmap(switch.mode)(trigger))
      return state.replace(trigger=trigger, mode=mode.astype(jp.int32)), switched

    def end_segment(state):
      """Middle transitions into the TD3 buffer and PPO rollout; the next modes and goals."""
      items, steps = jax.vmap(middle.close, in_axes=(0, None, None, 0))(
          state.segment, episode_end, state.low.params, jax.random.split(kc, E))
      state = state.replace(middle_buffer=buffers.add(state.middle_buffer, items))
      if has_ppo:
        slot = (t // c) % config.middle_rollout_length
        state = state.replace(middle_rollout=_write_slot(state.middle_rollout, slot, steps))
      m = {}
      if has_top:  # within a segment's end, the horizon flag is horizon_end
        state, hm = _gated(horizon_end, end_horizon, state)
        m.update(_prefixed("horizon", hm, horizon_end))
      if informed:
        state, switched = informed_switch(state, items)
        m["switch/switches"] = switched.sum().astype(jp.float32)
      state, decided = count(state, t + 1 >= config.warmup_steps, t + 1 >= live_from,
                             "mode_decisions", "mode_decisions_after_start")
      m.update({f"decisions/{name}": decided[j] for j, name in enumerate(hierarchy.MODES)})
      return new_segments(state, state.env.obs, kg, t + 1 < config.warmup_steps, t), m

    state, segment_m = _gated(segment_end, end_segment, state)  # zeros where skipped
    metrics.update(segment_m)
    state, update_m = _updates(state, t, live, segment_end, kl, km, kp, kev)
    metrics.update(update_m)
    return state, metrics

  def _updates(state, t, live, segment_end, kl, km, kp, kev):
    """Learning after warm-up, each level on its own clock, and the evaluation (S_E)."""

    def low_update(state):
      new, m = low.update(state.low, state.low_buffer, kl, t)
      return state.replace(low=new), m

    def middle_update(state):
      new, m = middle.td3_update(state.middle, state.middle_buffer, state.low.params, km, t)
      return state.replace(middle=new), m

    def middle_ppo_update(state):
      new, m = middle.ppo_update(state.middle_ppo, state.middle_rollout, t)
      return state.replace(middle_ppo=new), {**m, "std": middle.ppo_std(t)}

    def top_update(state):
      new, m = top.update(state.top, state.top_rollout, state.s_e)
      return state.replace(top=new), m

    def evaluation(state):
      s_e, dist, ret = evaluate(state.low.params, state.middle.params, kev)
      return (state.replace(s_e=s_e, eval_distance=dist, eval_return=ret),
              {"success": s_e, "distance": dist, "return": ret})

    gates = [("low", live, low_update), ("middle", live & segment_end, middle_update)]
    if has_ppo:
      every = config.middle_ppo_every
      gates.append(("middle_ppo", live & (t % every == every - 1), middle_ppo_update))
    if has_top:
      every = top_cfg.train_every
      gates.append(("top", live & (t % every == every - 1), top_update))
    gates.append(("eval", live & ((t + 1) % config.eval_every == 0), evaluation))
    metrics = {}
    for name, pred, fn in gates:
      state, m = _gated(pred, fn, state)
      metrics.update(_prefixed(name, m, pred))
    return state, metrics

  return Agent(config=config, env=env, low=low, middle=middle, top=top, switch=switch,
               init=init, step=step, evaluate=evaluate)
