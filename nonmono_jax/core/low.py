"""The Low level: a goal-conditioned TD3 that acts every env step (HIRO).

    a   = clip(pi_L(s, g) + N(0, sigma_L), +-limit)       (uniform random during warm-up)
    g'  = s[:3] + g - s'[:3];   r_L = -||g'||;   done_L = ||g'|| <= 1.5
    Low buffer <- (s, g, a, r_L, s', g', done_L);  ``updates`` TD3 updates per env step

``done_goal="current"`` tests the goal of the step instead, ||g|| <= 1.5 (the paper's code:
"s was already within 1.5 of its subgoal").
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp

from nonmono_jax.core import buffers, hierarchy, learning, td3
from nonmono_jax.core.numbers import Numbers


@dataclasses.dataclass(frozen=True)
class Low:
  td3: td3.TD3
  init_buffer: Callable[[], buffers.ReplayBuffer]
  act: Callable[..., jax.Array]
  transition: Callable[..., td3.Transition]
  update: Callable[..., tuple[td3.TD3State, dict]]


def make_low(obs_size: int, action_size: int, action_limit, config: td3.TD3Config,
             updates: int = 1, done_goal: str = "next") -> Low:
  k = hierarchy.GOAL_SIZE
  learner = td3.make_td3(obs_size, k, action_size, action_limit, config)
  lim = jp.broadcast_to(jp.asarray(action_limit, jp.float32), (action_size,))

  def act(params, obs, goal, key, warm, hp: Numbers):
    """The behaviour action: uniform during warm-up, else pi_L plus Gaussian noise (std
    ``hp.expl_noise``)."""
    k1, k2 = jax.random.split(key)
    random = jax.random.uniform(k1, (action_size,), minval=-lim, maxval=lim)
    return jp.where(warm, random, learner.explore(params, obs, goal, k2, hp.expl_noise))

  def transition(s, g, a, s_next):
    g_next = hierarchy.goal_transition(s, g, s_next)
    return td3.Transition(obs=s, context=g, action=a,
                          reward=hierarchy.low_reward(s, g, s_next), next_obs=s_next,
                          next_context=g_next,
                          done=hierarchy.low_done(g_next if done_goal == "next" else g))

  def update(state: td3.TD3State, buffer: buffers.ReplayBuffer, key, t, hp: Numbers):
    """``updates`` TD3 updates on batches from the Low buffer; metrics of the last."""

    def one(state, i):
      kb, ku = jax.random.split(jax.random.fold_in(key, i))
      batch = buffers.sample(buffer, kb, config.batch_size)
      n = t * updates + i  # the update counter: the delayed actor's clock
      return learner.update(state, batch, ku, n % config.policy_delay == 0, hp)

    return learning.repeat(one, state, updates)

  def init_buffer():
    vec = lambda n: jax.ShapeDtypeStruct((n,), jp.float32)
    example = jax.eval_shape(transition, vec(obs_size), vec(k), vec(action_size), vec(obs_size))
    return buffers.init(example, config.buffer_size)

  return Low(td3=learner, init_buffer=init_buffer,
             act=act, transition=transition, update=update)
