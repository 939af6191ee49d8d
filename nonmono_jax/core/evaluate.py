"""Evaluation of Middle TD3 + Low TD3 without exploration noise: the success rate S_E.

Each episode starts from a reset, the Middle TD3 picks a goal every c steps and the Low TD3
follows it with the goal transition in between (as in training; the paper's code re-queries
the Middle every step, docs/fidelity.md). An episode succeeds if the robot comes within the
task's success radius at any step. As in the paper's code, the policies are the *target*
actors by default (``target_networks``; S_E feeds the Top's loss). Episodes run vmapped inside one ``lax.scan``;
``make_episode`` is the episode itself, with a record of every step (also drawn by
``experiments/render.py``).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jp

from envs import rollout
from nonmono_jax.core import hierarchy


def make_episode(env, c: int, low_act: Callable, middle_act: Callable) -> Callable:
  """``episode(low_params, middle_params, key) -> (reset state, per-step records)``.

  ``low_act(params, obs, goal)`` and ``middle_act(params, obs)`` are the noiseless TD3
  policies (the Middle's towards the env's target: ``middle.Middle.policy``). Record t (of
  ``env.episode_length``): after step t the robot's ``pos``,
  ``success``, ``distance``, ``reward``, the ``blocks``' centres and whether the physics went
  ``unstable``, and the world point ``goal`` = s[:3] + g that the Low was sent to during step t.
  """
  def episode(low_params, middle_params, key):
    s0 = env.reset(key)

    def act(g, s, t):
      return low_act(low_params, s.obs, g)

    def observe(g, s, s2, t):
      """The goal transition, or the Middle's next goal every c steps; the step's record."""
      g2 = hierarchy.goal_transition(s.obs, g, s2.obs)
      g2 = jp.where((t + 1) % c == 0, middle_act(middle_params, s2.obs), g2)
      record = {"pos": s2.obs[:hierarchy.GOAL_SIZE], "goal": s.obs[:hierarchy.GOAL_SIZE] + g,
                "success": s2.success, "distance": s2.distance, "reward": s2.reward,
                "blocks": env.block_positions(s2), "unstable": env.unstable(s2)}
      return g2, record

    _, records = rollout.unroll(env, s0, act, jp.arange(env.episode_length),
                                middle_act(middle_params, s0.obs), observe)
    return s0, records

  return episode


def acting_params(params, target_networks: bool):
  """The TD3 params whose ``actor`` is evaluated: the target actor where ``target_networks``."""
  return params.replace(actor=params.target_actor) if target_networks else params


def make_evaluate(env, c: int, low_act: Callable, middle_act: Callable,
                  episodes: int, target_networks: bool = True) -> Callable:
  """``evaluate(low_params, middle_params, key) -> (S_E, mean final distance, mean return,
  unstable steps)``; the last counts the env steps whose physics went unstable (0 normally).

  ``low_params`` / ``middle_params`` are the levels' ``TD3Params``; their target actors act
  where ``target_networks`` (the paper's code), else the online actors.
  """
  episode = make_episode(env, c, low_act, middle_act)

  def evaluate(low_params, middle_params, key):
    low_params = acting_params(low_params, target_networks)
    middle_params = acting_params(middle_params, target_networks)

    def one(key):
      _, r = episode(low_params, middle_params, key)
      return r["success"].max(), r["distance"][-1], r["reward"].sum(), r["unstable"].sum()

    success, distance, ret, unstable = jax.vmap(one)(jax.random.split(key, episodes))
    return success.mean(), distance.mean(), ret.mean(), unstable.sum()

  return evaluate
