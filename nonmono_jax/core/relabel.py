"""HIRO's off-policy goal correction (Nachum et al. 2018, sec. 3.3) for the Middle TD3 buffer.

A Middle transition spans c low steps: states s_0..s_c, low actions a_0..a_{c-1}, and the goal
g the Middle emitted at s_0. The Low policy has changed since, so HIRO relabels g with the
candidate that best explains the stored low actions under the current low policy:

    candidates = [g, s_c - s_0, 8 x clip(N(s_c - s_0, 0.5 * goal_range), +-goal_range)]
    goals along the segment (goal transition): g_t = g + s_0 - s_t      (xyz part of s)
    log p(a | g~) = -1/2 sum_t || a_t - pi_L(s_t, g~_t) ||^2
    g* = argmax over candidates

The goal is a relative xyz offset: the first ``goal_size`` entries of the observation.

Exact ties (a Low policy whose actions do not depend on the goal, e.g. saturated in float32
tanh, scores every candidate alike) go to the original goal, then s_c - s_0, then the random
ones (``ties="original"``), or as the paper's code orders its candidates, the random ones
first, then s_c - s_0, then the goal (``ties="random"``, ``off_policy_correction``).
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jp

from nonmono_jax.core.config import RELABEL_TIES as TIES  # which candidate wins an exact tie

N_RANDOM = 8  # HIRO: 8 random candidates + the original goal + s_c - s_0


def goal_sequence(goal: jax.Array, states: jax.Array) -> jax.Array:
  """(c, goal_size) goals g_t = g + s_0 - s_t along a segment of c states."""
  k = goal.shape[-1]
  return goal + states[0, :k] - states[:, :k]


def candidates(key: jax.Array, goal: jax.Array, s_first: jax.Array, s_last: jax.Array,
               goal_range: jax.Array, n_random: int = N_RANDOM) -> jax.Array:
  """(n_random + 2, goal_size): the original goal, s_c - s_0, and Gaussian ones around it."""
  k = goal.shape[-1]
  diff = s_last[:k] - s_first[:k]
  noise = jax.random.normal(key, (n_random, k)) * 0.5 * goal_range
  random = jp.clip(diff + noise, -goal_range, goal_range)
  return jp.concatenate([goal[None], diff[None], random])


def action_log_likelihood(low_policy: Callable[[jax.Array, jax.Array], jax.Array],
                          states: jax.Array, actions: jax.Array, goal: jax.Array) -> jax.Array:
  """-1/2 sum_t ||a_t - pi_L(s_t, g_t)||^2 for the goal g held from s_0 (states: c of them)."""
  pred = low_policy(states, goal_sequence(goal, states))
  return -0.5 * jp.sum(jp.square(actions - pred))


def relabel(key: jax.Array, low_policy: Callable[[jax.Array, jax.Array], jax.Array],
            states: jax.Array, actions: jax.Array, goal: jax.Array, goal_range: jax.Array,
            n_random: int = N_RANDOM, ties: str = "original") -> tuple[jax.Array, jax.Array]:
  """(relabelled goal, index of the chosen candidate) for one Middle transition.

  Args:
    key: PRNG key for the random candidates.
    low_policy: ``pi_L(states, goals) -> actions`` (batched over the leading axis).
    states: (c + 1, obs) low observations s_0..s_c of the segment.
    actions: (c, action) the low actions taken at s_0..s_{c-1}.
    goal: (goal_size,) the goal the Middle emitted at s_0.
    goal_range: (goal_size,) the Middle's action bound.
    ties: ``TIES``: which candidate wins an exact tie.
  """
  if ties not in TIES:
    raise ValueError(f"ties must be one of {', '.join(TIES)}, got {ties!r}")
  cands = candidates(key, goal, states[0], states[-1], goal_range, n_random)
  logp = jax.vmap(lambda g: action_log_likelihood(low_policy, states[:-1], actions, g))(cands)
  if ties == "original":
    best = jp.argmax(logp)
  else:  # the code's order: the random candidates, s_c - s_0, the goal; argmax takes the first
    order = jp.concatenate([jp.arange(2, n_random + 2), jp.array([1, 0])])
    best = order[jp.argmax(logp[order])]
  return cands[best], best
