"""HIRO's chooser (switch "none"): TD3 goals always; no state, nothing to learn."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import hierarchy
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import Numbers
from nonmono_jax.core.modes import Decision


@struct.dataclass
class Fixed:
  """HIRO's chooser has no state."""

  def learner_params(self) -> dict:
    return {}


@dataclasses.dataclass(frozen=True)
class FixedChooser:
  """HIRO: TD3 goals always."""

  num_envs: int
  live_from: int
  name = "none"
  starting_mode = hierarchy.TD3

  def init(self, keys, obs, middle_params) -> tuple[Fixed, jax.Array]:
    return Fixed(), jp.full((self.num_envs,), hierarchy.TD3, jp.int32)

  def accumulate(self, state, reward, success):
    return state

  def decide(self, state, mode, decision: Decision, keys, hp: Numbers):
    return state, mode, {}

  def update(self, state, t, live, s_e, hp: Numbers):
    return state, {}


def make(config: AgentConfig, obs_size: int, target, value) -> FixedChooser:
  return FixedChooser(num_envs=config.num_envs, live_from=config.warmup_steps)
