"""One env step of the hierarchical agent, for one seed (vmap over seeds, scan over time).

So far the two HIRO levels (Middle TD3 with Gaussian goal noise, goal-conditioned Low TD3);
the Top PPO and the mode switch of the paper's Algorithm 1 build on this step.

    a    = clip(pi_L(s, g) + N(0, sigma_L))          (uniform random during warm-up)
    s'   = env.step(s, a);  g' = s[:3] + g - s'[:3];  r_L = -||g'||
    Low buffer  <- (s, g, a, r_L, s', g', ||g'|| <= 1.5);  Low TD3 update (after warm-up)
    every c steps (Middle horizon):
      Middle buffer <- (s_0, target, g_0, 0.1 sum R, s_c, target) + the segment (s_0..s_c, a)
      g = clip(pi_M(s_c, target) + N(0, sigma_M), +-goal_range)  (uniform during warm-up)
      Middle TD3 update on relabelled goals (after warm-up)
    episode end: reset (episodes are synchronised across seeds: a fixed length, no termination)

Every gate (warm-up, Middle horizon, episode end, delayed actor) is a function of the global
step ``t``, which is not batched over seeds, so each stays a real ``lax.cond`` under ``vmap``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax import buffers, hierarchy, relabel, td3


@dataclasses.dataclass(frozen=True)
class AgentConfig:
  """The hierarchy's options; defaults are SPEC section 2 (Ant tasks)."""

  c: int = 10  # Middle horizon
  goal_range: tuple[float, float, float] = (10.0, 10.0, 0.5)
  warmup_steps: int = 100_000  # random low actions and goals, no updates
  middle_goal_noise: float = 1.0  # HIRO: Gaussian goal noise, std per dim
  low: td3.TD3Config = td3.TD3Config()
  middle: td3.TD3Config = td3.TD3Config()

  def __post_init__(self):
    if self.c < 1:
      raise ValueError(f"c must be >= 1, got {self.c}")
    if len(self.goal_range) != hierarchy.GOAL_SIZE:
      raise ValueError(f"goal_range must have {hierarchy.GOAL_SIZE} entries (x, y, z), "
                       f"got {self.goal_range}")
    if any(r < 0 for r in self.goal_range):
      raise ValueError(f"goal_range must be >= 0, got {self.goal_range}")
    if self.warmup_steps < 0:
      raise ValueError(f"warmup_steps must be >= 0, got {self.warmup_steps}")
    if self.middle_goal_noise < 0:
      raise ValueError(f"middle_goal_noise must be >= 0, got {self.middle_goal_noise}")


@struct.dataclass
class Segment:
  """The low steps under the current Middle goal (for the Middle transition and relabelling)."""

  obs: jax.Array  # (c + 1, obs): s_0 .. s_c
  actions: jax.Array  # (c, action)
  rewards: jax.Array  # (c,) task rewards
  goal: jax.Array  # (3,) the goal the Middle emitted at s_0


@struct.dataclass
class SeedState:
  """Everything one seed owns."""

  env: Any  # envs.MazeState
  low: td3.TD3State
  middle: td3.TD3State
  low_buffer: buffers.ReplayBuffer
  middle_buffer: buffers.ReplayBuffer
  goal: jax.Array
  segment: Segment
  key: jax.Array


@dataclasses.dataclass(frozen=True)
class Agent:
  """Pure functions of the agent: ``init(key) -> SeedState``, ``step(state, t)``."""

  config: AgentConfig
  low: td3.TD3
  middle: td3.TD3
  init: Callable[[jax.Array], SeedState]
  step: Callable[[SeedState, jax.Array], tuple[SeedState, dict]]
  middle_goal: Callable[..., jax.Array]


def make_agent(env, config: AgentConfig = AgentConfig()) -> Agent:
  """Build the agent for an env of ``envs`` (obs[:3] is the robot's xyz)."""
  if env.episode_length % config.c:
    raise ValueError(f"episode_length ({env.episode_length}) must be a multiple of c "
                     f"({config.c}): Middle segments end with episodes")
  obs_size, act_size, k = env.observation_size, env.action_size, hierarchy.GOAL_SIZE
  goal_range = jp.asarray(config.goal_range, jp.float32)
  target = jp.asarray(env.target, jp.float32)
  lim = env.action_limit
  low = td3.make_td3(obs_size, k, act_size, lim, config.low)
  middle = td3.make_td3(obs_size, k, k, goal_range, config.middle)
  c = config.c

  def middle_goal(middle_params, obs, key, warm):
    """pi_M(s, target) + N(0, sigma_M), clipped; uniform over the range during warm-up."""
    k1, k2 = jax.random.split(key)
    random = jax.random.uniform(k1, (k,), minval=-goal_range, maxval=goal_range)
    noisy = middle.explore(middle_params, obs, target, k2, config.middle_goal_noise)
    return jp.where(warm, random, noisy)

  def empty_segment(obs, goal):
    return Segment(obs=jp.zeros((c + 1, obs_size)).at[0].set(obs),
                   actions=jp.zeros((c, act_size)), rewards=jp.zeros((c,)), goal=goal)

  low_example = td3.Transition(obs=jp.zeros(obs_size), context=jp.zeros(k),
                               action=jp.zeros(act_size), reward=jp.zeros(()),
                               next_obs=jp.zeros(obs_size), next_context=jp.zeros(k),
                               done=jp.zeros(()))
  middle_example = {
      "transition": td3.Transition(obs=jp.zeros(obs_size), context=jp.zeros(k),
                                   action=jp.zeros(k), reward=jp.zeros(()),
                                   next_obs=jp.zeros(obs_size), next_context=jp.zeros(k),
                                   done=jp.zeros(())),
      "states": jp.zeros((c + 1, obs_size)),
      "actions": jp.zeros((c, act_size)),
  }

  def init(key):
    ke, kl, km, kg, key = jax.random.split(key, 5)
    env_state = env.reset(ke)
    low_state, middle_state = low.init(kl), middle.init(km)
    goal = middle_goal(middle_state.params, env_state.obs, kg, True)
    return SeedState(
        env=env_state, low=low_state, middle=middle_state,
        low_buffer=buffers.init(low_example, config.low.buffer_size),
        middle_buffer=buffers.init(middle_example, config.middle.buffer_size),
        goal=goal, segment=empty_segment(env_state.obs, goal), key=key)

  def low_update(state, key, t):
    batch = buffers.sample(state.low_buffer, key, config.low.batch_size)
    new, metrics = low.update(state.low, batch, jax.random.fold_in(key, 1),
                              t % config.low.policy_delay == 0)
    return state.replace(low=new), metrics

  def middle_update(state, key, t):
    k1, k2, k3 = jax.random.split(key, 3)
    sample = buffers.sample(state.middle_buffer, k1, config.middle.batch_size)
    policy = lambda s, g: low.act(state.low.params, s, g)
    goals, _ = jax.vmap(lambda kk, s, a, g: relabel.relabel(kk, policy, s, a, g, goal_range))(
        jax.random.split(k2, config.middle.batch_size), sample["states"], sample["actions"],
        sample["transition"].action)
    batch = sample["transition"].replace(action=goals)
    update_actor = (t // c) % config.middle.policy_delay == 0
    new, metrics = middle.update(state.middle, batch, k3, update_actor)
    return state.replace(middle=new), metrics

  def step(state: SeedState, t):
    """One env step at global step ``t`` (unbatched)."""
    key, ka, kg, kr, kl, km = jax.random.split(state.key, 6)
    warm = t < config.warmup_steps
    s = state.env.obs
    a_random = jax.random.uniform(ka, (act_size,), minval=-lim, maxval=lim)
    a_policy = low.explore(state.low.params, s, state.goal, ka)
    a = jp.where(warm, a_random, a_policy)
    env_next = env.step(state.env, a)
    s_next = env_next.obs
    g_next = hierarchy.goal_transition(s, state.goal, s_next)
    low_tr = td3.Transition(obs=s, context=state.goal, action=a,
                            reward=hierarchy.low_reward(s, state.goal, s_next),
                            next_obs=s_next, next_context=g_next,
                            done=hierarchy.low_done(g_next))
    low_buffer = buffers.add(state.low_buffer, jax.tree.map(lambda x: x[None], low_tr))
    i = t % c
    seg = state.segment.replace(obs=state.segment.obs.at[i + 1].set(s_next),
                                actions=state.segment.actions.at[i].set(a),
                                rewards=state.segment.rewards.at[i].set(env_next.reward))
    state = state.replace(env=env_next, low_buffer=low_buffer, goal=g_next, segment=seg, key=key)

    # An episode ends only at a segment's end (episode_length is a multiple of c), after
    # s_c is stored, so the reset comes first and the next goal is chosen from the new state.
    episode_end = (t + 1) % env.episode_length == 0
    state = jax.lax.cond(episode_end, lambda s: s.replace(env=env.reset(kr)), lambda s: s, state)

    def end_segment(state):
      """Middle transition into its buffer; the Middle's next goal starts a new segment."""
      seg = state.segment
      tr = td3.Transition(obs=seg.obs[0], context=target, action=seg.goal,
                          reward=hierarchy.middle_reward(seg.rewards), next_obs=seg.obs[c],
                          next_context=target, done=jp.zeros(()))
      item = {"transition": tr, "states": seg.obs, "actions": seg.actions}
      mbuf = buffers.add(state.middle_buffer, jax.tree.map(lambda x: x[None], item))
      goal = middle_goal(state.middle.params, state.env.obs, kg, warm)
      return state.replace(middle_buffer=mbuf, goal=goal,
                           segment=empty_segment(state.env.obs, goal))

    state = jax.lax.cond(i == c - 1, end_segment, lambda s: s, state)

    zeros = {"critic_loss": jp.zeros(()), "q": jp.zeros(()), "target_q": jp.zeros(()),
             "actor_loss": jp.zeros(())}
    state, low_m = jax.lax.cond(warm, lambda s: (s, zeros), lambda s: low_update(s, kl, t), state)
    state, mid_m = jax.lax.cond(warm | (i != c - 1), lambda s: (s, zeros),
                                lambda s: middle_update(s, km, t), state)
    metrics = {"reward": env_next.reward, "success": env_next.metrics["success"],
               "distance": env_next.metrics["distance"], "low/reward": low_tr.reward,
               **{f"low/{n}": v for n, v in low_m.items()},
               **{f"middle/{n}": v for n, v in mid_m.items()}}
    return state, metrics

  return Agent(config=config, low=low, middle=middle, init=init, step=step,
               middle_goal=middle_goal)
