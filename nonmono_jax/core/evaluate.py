"""Evaluation without exploration noise: the success rate S_E, in one of three kinds.

    held     the Middle TD3 picks a goal every c steps and the Low follows it with the goal
             transition in between, as the agent acts in training (ours' first reading)
    requery  the paper's code (``hiro.evaluate``, its 'success rate', the S_E its Top loss
             reads and its figures plot): the first goal is N(0, I) (its ``randn(3)``), then
             after every env step the Middle TD3 gives a new goal from the new state; no goal
             transition
    ppo      the code's 'higher success rate' (``evaluate_higher_policy``): the same with the
             Middle PPO's sampled goal (clipped to the goal range) at every step

An episode succeeds if the robot comes within the task's success radius after any step. The
code stops an episode at its first success; ours runs every episode to its end, so its final
distance is read where the code's would stop (``requery``, ``ppo``) or at the end (``held``).
As in the paper's code, the TD3 policies are the *target* actors by default
(``target_networks``). Episodes run vmapped inside one ``lax.scan``; ``make_episode`` is the
episode itself, with a record of every step (also drawn by ``experiments/render.py``). The
evaluations of one call start from the same reset states (the same keys), kind by kind.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp
from flax import struct

from envs import rollout
from nonmono_jax.core import hierarchy
from nonmono_jax.core.config import EVAL_KINDS as KINDS  # the order of ``Evaluation.by_kind``


@struct.dataclass
class Outcome:
  """What episodes of one kind give: per episode (``outcome``), or their means (``Evaluator``)."""

  success: jax.Array  # 1.0 if the robot came within the success radius after any step
  distance: jax.Array  # the final distance to the target (where the kind reads it)
  return_: jax.Array  # the return up to there
  unstable: jax.Array  # env steps whose physics went unstable (0 normally)


@struct.dataclass
class Evaluation:
  """One evaluation of a seed: S_E of the run's kind and the other kinds' S_E."""

  success: jax.Array  # S_E of the run's kind (``eval_goal``): what the Top's loss reads
  distance: jax.Array  # its mean final distance to the target
  return_: jax.Array  # its mean return (up to where the final distance is read)
  unstable: jax.Array  # env steps whose physics went unstable in it (0 normally)
  by_kind: jax.Array  # (3,) S_E of each kind in KINDS; 0 for a kind not run


def make_episode(env, c: int, low_act: Callable, goal_act: Callable,
                 kind: str = "held") -> Callable:
  """``episode(low_params, goal_params, key) -> (reset state, per-step records)``.

  ``low_act(params, obs, goal)`` is the noiseless Low; ``goal_act(params, obs, key)`` the
  Middle sub-policy that gives goals (the noiseless Middle TD3 towards the env's target for
  ``held`` and ``requery``, the Middle PPO's sample for ``ppo``). Record t (of
  ``env.episode_length``): after step t the robot's ``pos``, ``success``, ``distance``,
  ``reward``, the ``blocks``' centres and whether the physics went ``unstable``, and the
  world point ``goal`` = s[:3] + g that the Low was sent to during step t. The reset uses
  ``key`` itself, so every kind starts from the same state for one key.
  """
  if kind not in KINDS:
    raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")

  def episode(low_params, goal_params, key):
    s0 = env.reset(key)
    step_keys = jax.random.split(jax.random.fold_in(key, 2), env.episode_length)

    def act(g, s, x):
      return low_act(low_params, s.obs, g)

    def observe(g, s, s2, x):
      t, k = x
      if kind == "held":  # the goal transition; the Middle's next goal every c steps
        g2 = hierarchy.goal_transition(s.obs, g, s2.obs)
        g2 = jp.where((t + 1) % c == 0, goal_act(goal_params, s2.obs, k), g2)
      else:  # a new goal after every step
        g2 = goal_act(goal_params, s2.obs, k)
      record = {"pos": s2.obs[:hierarchy.GOAL_SIZE], "goal": s.obs[:hierarchy.GOAL_SIZE] + g,
                "success": s2.success, "distance": s2.distance, "reward": s2.reward,
                "blocks": env.block_positions(s2), "unstable": env.unstable(s2)}
      return g2, record

    first = (goal_act(goal_params, s0.obs, jax.random.fold_in(key, 1)) if kind == "held"
             else jax.random.normal(jax.random.fold_in(key, 1), (hierarchy.GOAL_SIZE,)))
    _, records = rollout.unroll(env, s0, act, (jp.arange(env.episode_length), step_keys),
                                first, observe)
    return s0, records

  return episode


def outcome(records, kind: str) -> Outcome:
  """The ``Outcome`` of one episode's records: the final distance where the code's episode
  would stop (its first success) for ``requery`` and ``ppo``, at the episode's end for
  ``held``."""
  success, unstable = records["success"].max(), records["unstable"].sum()
  if kind == "held":
    return Outcome(success=success, distance=records["distance"][-1],
                   return_=records["reward"].sum(), unstable=unstable)
  n = records["success"].shape[0]
  last = jp.where(success > 0, jp.argmax(records["success"] > 0), n - 1)
  return Outcome(success=success, distance=records["distance"][last],
                 return_=jp.where(jp.arange(n) <= last, records["reward"], 0.0).sum(),
                 unstable=unstable)


def acting_params(params, target_networks: bool):
  """The TD3 params whose ``actor`` is evaluated: the target actor where ``target_networks``."""
  return params.replace(actor=params.target_actor) if target_networks else params


@dataclasses.dataclass(frozen=True)
class Evaluator:
  """``evaluate(low_params, middle_params, ppo_params, key) -> Evaluation`` (``make_evaluate``).

  ``kinds``: the kinds it runs, the run's own (``main``) first.
  """

  kinds: tuple[str, ...]
  evaluate: Callable[..., Evaluation]

  def __call__(self, low_params, middle_params, ppo_params, key) -> Evaluation:
    return self.evaluate(low_params, middle_params, ppo_params, key)


def make_evaluate(env, c: int, low_act: Callable, middle_act: Callable, episodes: int,
                  target_networks: bool = True, main: str = "held", extra=(),
                  ppo_act: Callable | None = None) -> Evaluator:
  """The evaluation of a seed: ``episodes`` episodes of ``main`` (its S_E is the run's), and
  of each kind in ``extra`` (``ppo`` only where ``ppo_act`` is given), for their S_E alone.

  ``middle_act(params, obs)`` is the noiseless Middle TD3, ``ppo_act(params, obs, key)`` the
  Middle PPO's clipped sample; ``low_params`` / ``middle_params`` are the levels'
  ``TD3Params``, whose target actors act where ``target_networks`` (the paper's code). The
  main kind's episodes take ``jax.random.split(key, episodes)``; another kind's the same keys
  (the same start states), so one call compares the kinds on one set of starts.
  """
  td3_act = lambda params, obs, key: middle_act(params, obs)
  kinds = (main,) + tuple(k for k in KINDS if k in extra and k != main
                          and (k != "ppo" or ppo_act is not None))
  runs = {k: make_episode(env, c, low_act, ppo_act if k == "ppo" else td3_act, k)
          for k in kinds}

  def evaluate(low_params, middle_params, ppo_params, key):
    low_params = acting_params(low_params, target_networks)
    middle_params = acting_params(middle_params, target_networks)
    keys = jax.random.split(key, episodes)
    results = {}
    for k in kinds:
      params = ppo_params if k == "ppo" else middle_params
      one = lambda kk, k=k, params=params: outcome(runs[k](low_params, params, kk)[1], k)
      o = jax.vmap(one)(keys)
      results[k] = Outcome(success=o.success.mean(), distance=o.distance.mean(),
                           return_=o.return_.mean(), unstable=o.unstable.sum())
    ran = results[main]
    by_kind = jp.stack([results[k].success if k in results else jp.zeros(()) for k in KINDS])
    return Evaluation(success=ran.success, distance=ran.distance, return_=ran.return_,
                      unstable=ran.unstable, by_kind=by_kind)

  return Evaluator(kinds=kinds, evaluate=evaluate)
