"""The formulas that tie the three levels together (docs/spec.md section 2, the paper's Algorithm 1).

Modes of the Top level, g_expl_mode, in the order of the paper's alpha and S_O tuples:
TD3 (exploit), PPO (explore) and RANDOM (explore).

Low <- Middle (HIRO):
  goal transition   g' = s[:3] + g - s'[:3]        (the goal stays fixed in world space)
  low reward        r_L = -|| s[:3] + g - s'[:3] || = -||g'||
  low done          ||g'|| <= 1.5
Middle reward       R_M = 0.1 * (sum of the c task rewards of its goal)
Top, after each Top horizon (50 steps) run in mode m:
  S_O_m  = Done_m / Count_m          (the fraction of steps within the success radius)
  done_m = S_O_m >= S_O[m]
  R_final = R_m + alpha[m] * R_m     (R_m: the sum of task rewards; rewards are negative, so
                                      alpha > 0 penalises a mode: "larger alpha, rarer mode")
"""

from __future__ import annotations

import jax
import jax.numpy as jp

# declared with the config, which imports no JAX
from nonmono_jax.core.config import GOAL_SIZE, MODES, PPO, RANDOM, TD3  # noqa: F401

LOW_DONE_DISTANCE = 1.5
MIDDLE_REWARD_SCALE = 0.1


def goal_transition(s: jax.Array, g: jax.Array, s_next: jax.Array) -> jax.Array:
  """g' = s[:3] + g - s'[:3]."""
  return s[..., :GOAL_SIZE] + g - s_next[..., :GOAL_SIZE]


def low_reward(s: jax.Array, g: jax.Array, s_next: jax.Array) -> jax.Array:
  """r_L = -||s[:3] + g - s'[:3]||."""
  return -jp.linalg.norm(goal_transition(s, g, s_next), axis=-1)


def low_done(g_next: jax.Array, distance: float = LOW_DONE_DISTANCE) -> jax.Array:
  """1.0 where the remaining goal offset is within ``distance`` (1.5)."""
  return (jp.linalg.norm(g_next, axis=-1) <= distance).astype(jp.float32)


def middle_reward(task_rewards: jax.Array, scale: float = MIDDLE_REWARD_SCALE) -> jax.Array:
  """R_M = 0.1 * sum of the task rewards collected under one Middle goal (last axis)."""
  return scale * jp.sum(task_rewards, axis=-1)


def success_ratio(done_count: jax.Array, count: jax.Array) -> jax.Array:
  """S_O_m = Done_m / Count_m (0 for an empty horizon)."""
  return jp.where(count > 0, done_count / jp.maximum(count, 1), 0.0)


def top_done(s_o_m: jax.Array, s_o: jax.Array, mode: jax.Array) -> jax.Array:
  """done_m = S_O_m >= S_O[mode], as 0/1."""
  return (s_o_m >= jp.asarray(s_o)[mode]).astype(jp.float32)


def modified_reward(r_m: jax.Array, alpha: jax.Array, mode: jax.Array) -> jax.Array:
  """R_final = R_m + alpha[mode] * R_m (Eq. 6 of the paper)."""
  return r_m + jp.asarray(alpha)[mode] * r_m
