"""The formulas that tie the Low and the Middle together (docs/spec.md section 2, the paper's
Algorithm 1); the Top's own (S_O_m, done_m, R_final, its loss weights) are in ``modes/top.py``.

Modes of the Top level, g_expl_mode, in the order of the paper's alpha and S_O tuples:
TD3 (exploit), PPO (explore) and RANDOM (explore).

Low <- Middle (HIRO):
  goal transition   g' = s[:3] + g - s'[:3]        (the goal stays fixed in world space)
  low reward        r_L = -|| s[:3] + g - s'[:3] || = -||g'||
  low done          ||g'|| <= 1.5
Middle reward       R_M = 0.1 * (sum of the c task rewards of its goal)
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
