"""The Middle level: three sub-policies that emit a goal every c steps, and their learners.

g_expl_mode picks which one emits the next goal (a relative xyz offset within +-goal_range):

    TD3     g = clip(pi_M(s, target) + N(0, sigma_M))     sigma_M: HIRO 1, ours 0
    PPO     g = clip(N(mu_M(s, target), std_t * range))   std_t decays 0.6 -> 0.1
    RANDOM  g ~ U(-range, range)                          (or the paper code's clip(randn*range))

Every Middle transition (s_0, target, g, R_M = 0.1 sum R, s_c), whichever mode chose g, feeds
both learners: the Middle TD3 buffer (with the segment's states and low actions for HIRO's
off-policy relabelling) and the Middle PPO rollout (with log pi_PPO(g | s_0) at collection).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax import buffers, hierarchy, ppo, relabel, td3
from nonmono_jax.config import AgentConfig


@struct.dataclass
class Segment:
  """The low steps under one Middle goal, for the Middle transition and relabelling."""

  obs: jax.Array  # (c + 1, obs): s_0 .. s_c
  actions: jax.Array  # (c, action)
  rewards: jax.Array  # (c,) task rewards
  goal: jax.Array  # (3,) the goal emitted at s_0
  log_prob: jax.Array  # () log pi_PPO(goal | s_0, target), for the Middle PPO


@dataclasses.dataclass(frozen=True)
class Middle:
  td3: td3.TD3
  ppo: ppo.PPO | None  # None where the method has no Middle PPO
  init_buffer: Callable[[], buffers.ReplayBuffer]
  init_rollout: Callable[[], ppo.Rollout]
  goal: Callable[..., tuple[jax.Array, jax.Array]]
  new_segment: Callable[..., Segment]
  record: Callable[..., Segment]
  close: Callable[..., tuple[dict, ppo.Rollout]]
  td3_update: Callable[..., tuple[td3.TD3State, dict]]
  ppo_update: Callable[..., tuple[ppo.PPOState, dict]]
  ppo_std: Callable[[jax.Array], jax.Array]


def make_middle(obs_size: int, action_size: int, target, config: AgentConfig) -> Middle:
  k, c = hierarchy.GOAL_SIZE, config.c
  goal_range = jp.asarray(config.goal_range, jp.float32)
  target = jp.asarray(target, jp.float32)
  learner = td3.make_td3(obs_size, k, k, goal_range, config.middle)
  explorer = (ppo.make_ppo(obs_size + k, k, config.middle_ppo, goal_range)
              if config.uses_middle_ppo else None)
  n_rollout = config.middle_rollout_length

  def ppo_std(t):
    return ppo.gaussian_std(t, config.middle_ppo)

  def random_goal(key):
    if config.random_goal == "uniform":
      return jax.random.uniform(key, (k,), minval=-goal_range, maxval=goal_range)
    return jp.clip(jax.random.normal(key, (k,)) * goal_range, -goal_range, goal_range)

  def goal(td3_params, ppo_params, obs, mode, key, warm, t):
    """(goal, log pi_PPO(goal | s, target)) from the sub-policy ``mode`` (random in warm-up)."""
    k1, k2, k3 = jax.random.split(key, 3)
    g_random = random_goal(k1)
    g_td3 = learner.explore(td3_params, obs, target, k2, config.middle_goal_noise)
    if explorer is None:
      g = jp.where(warm | (mode == hierarchy.RANDOM), g_random, g_td3)
      return g, jp.zeros(())
    std = ppo_std(t)
    ppo_obs = jp.concatenate([obs, target])
    g_ppo = jp.clip(explorer.act(ppo_params, ppo_obs, k3, std)[0], -goal_range, goal_range)
    g = jp.select([warm | (mode == hierarchy.RANDOM), mode == hierarchy.PPO],
                  [g_random, g_ppo], g_td3)
    return g, explorer.log_prob(ppo_params, ppo_obs, g, std)

  def new_segment(obs, g, log_prob):
    return Segment(obs=jp.zeros((c + 1, obs_size)).at[0].set(obs),
                   actions=jp.zeros((c, action_size)), rewards=jp.zeros((c,)), goal=g,
                   log_prob=log_prob)

  def record(seg: Segment, i, a, s_next, reward):
    """Step ``i`` of the segment: action a_i, then s_{i+1} and the task reward."""
    return seg.replace(obs=seg.obs.at[i + 1].set(s_next), actions=seg.actions.at[i].set(a),
                       rewards=seg.rewards.at[i].set(reward))

  def close(seg: Segment, episode_end):
    """The segment's Middle TD3 buffer item and Middle PPO rollout step."""
    reward = hierarchy.middle_reward(seg.rewards)
    tr = td3.Transition(obs=seg.obs[0], context=target, action=seg.goal, reward=reward,
                        next_obs=seg.obs[c], next_context=target, done=jp.zeros(()))
    step = ppo.Rollout(obs=jp.concatenate([seg.obs[0], target]), action=seg.goal,
                       log_prob=seg.log_prob, reward=reward,
                       done=jp.asarray(episode_end, jp.float32))
    return {"transition": tr, "states": seg.obs, "actions": seg.actions}, step

  def init_buffer():
    item, _ = close(new_segment(jp.zeros(obs_size), jp.zeros(k), jp.zeros(())), False)
    return buffers.init(item, config.middle.buffer_size)

  def init_rollout():
    _, step = close(new_segment(jp.zeros(obs_size), jp.zeros(k), jp.zeros(())), False)
    return jax.tree.map(lambda x: jp.zeros((n_rollout,) + x.shape, x.dtype), step)

  def td3_update(state: td3.TD3State, buffer, low_act, key, t):
    """``middle_updates`` TD3 updates on relabelled batches; ``low_act(obs, goal)`` is pi_L."""
    cfg = config.middle

    def one(state, i):
      k1, k2, k3 = jax.random.split(jax.random.fold_in(key, i), 3)
      sample = buffers.sample(buffer, k1, cfg.batch_size)
      goals, _ = jax.vmap(lambda kk, s, a, g: relabel.relabel(kk, low_act, s, a, g, goal_range))(
          jax.random.split(k2, cfg.batch_size), sample["states"], sample["actions"],
          sample["transition"].action)
      n = (t // c) * config.middle_updates + i
      return learner.update(state, sample["transition"].replace(action=goals), k3,
                            n % cfg.policy_delay == 0)

    state, metrics = jax.lax.scan(one, state, jp.arange(config.middle_updates))
    return state, jax.tree.map(lambda m: m[-1], metrics)

  def ppo_update(state: ppo.PPOState, rollout: ppo.Rollout, t):
    return explorer.update(state, rollout, ppo_std(t))

  return Middle(td3=learner, ppo=explorer, init_buffer=init_buffer, init_rollout=init_rollout,
                goal=goal, new_segment=new_segment, record=record, close=close,
                td3_update=td3_update, ppo_update=ppo_update, ppo_std=ppo_std)
