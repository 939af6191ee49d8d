"""Evaluation of Middle TD3 + Low TD3 without exploration noise: the success rate S_E.

Each episode starts from a reset, the Middle TD3 picks a goal every c steps and the Low TD3
follows it with the goal transition in between (as in training; the paper's code re-queries
the Middle every step, SPEC section 5). An episode succeeds if the robot comes within the
task's success radius at any step. Episodes run vmapped inside one ``lax.scan``.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jp

from nonmono_jax import hierarchy


def make_evaluate(env, c: int, low_act: Callable, middle_act: Callable,
                  episodes: int) -> Callable:
  """``evaluate(low_params, middle_params, key) -> (S_E, mean final distance, mean return)``.

  ``low_act(params, obs, goal)`` and ``middle_act(params, obs, target)`` are the noiseless
  TD3 policies.
  """
  target = jp.asarray(env.target, jp.float32)

  def evaluate(low_params, middle_params, key):
    def episode(key):
      s = env.reset(key)
      g = middle_act(middle_params, s.obs, target)

      def body(carry, t):
        s, g = carry
        a = low_act(low_params, s.obs, g)
        s2 = env.step(s, a)
        g2 = hierarchy.goal_transition(s.obs, g, s2.obs)
        g2 = jp.where((t + 1) % c == 0, middle_act(middle_params, s2.obs, target), g2)
        return (s2, g2), (s2.metrics["success"], s2.reward)

      (s_end, _), (success, reward) = jax.lax.scan(body, (s, g), jp.arange(env.episode_length))
      return success.max(), s_end.metrics["distance"], reward.sum()

    success, distance, ret = jax.vmap(episode)(jax.random.split(key, episodes))
    return success.mean(), distance.mean(), ret.mean()

  return evaluate
