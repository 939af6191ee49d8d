"""The traced hyperparameters: the numbers of a config that only enter arithmetic, as a pytree.

A config (``AgentConfig``) stays the user's: frozen, checked, saved in ``config.json``. The
jitted program is built from its *static* part and reads its *traced* part at run time:

    static_key(config)   the config with every TRACED field at AgentConfig()'s value: configs
                         with equal static keys build the same program (they can be lanes of it)
    of(config)           Hyper: the TRACED fields as numbers (constants where closed over)
    stack(configs)       Hyper of float32 arrays with a leading variant axis (lanes' arguments)

    trainer = train.make_group_trainer(env, [ours, ours_no_mods], num_seeds=4, chunk_steps=200)

A switch that only turns a term on or off is a 0/1 weight here: ``top.reward_mod`` is folded
into alpha (alpha = 0 without it) and ``top.loss_mod`` is the weight of S_E in Train_T's loss
weights (1 - w S_E for TD3, 1 + w S_E for the explore modes). Both are exact in float32 at 0
and 1, so a variant alone computes what it computed when they were Python branches.
The learners' numbers (learning rates, gamma, tau, noises, PPO's clip and coefficients) are
traced too: each learner's ``TD3Hyper`` / ``PPOHyper``, the learning rates scaling the
updates of ``optax.adam(1.0)`` (``learning.gradient_step``). Everything else (sizes, c,
horizons, schedules, which learners and which switch exist) is static: docs/training.md,
"Variants as lanes".
"""

from __future__ import annotations

import jax
import numpy as np
from flax import struct

from nonmono_jax import ppo, td3
from nonmono_jax.config import AgentConfig, TopConfig, differences, get, override

# The dotted AgentConfig fields that are lanes' data, not program structure.
TRACED = ("top.alpha", "top.reward_mod", "top.s_o", "top.s_o_start", "top.loss_mod",
          "homeostasis.rho", "middle_goal_noise",
          *(f"{level}.{f}" for level in ("low", "middle") for f in td3.TRACED),
          *(f"{level}.{f}" for level in ("middle_ppo", "top.ppo") for f in ppo.TRACED))


@struct.dataclass
class TopHyper:
  """The Top's numbers (``top.py``): R_final's alpha, the S_O thresholds, the S_E weight."""

  alpha: jax.Array  # (3,) alpha[m]; zeros without the reward modification
  s_o: jax.Array  # (3,) S_O[m]: done_m = S_O_m >= S_O[m]
  s_o_start: jax.Array  # () S_O during the starting mode
  s_e_weight: jax.Array  # () 1 with the loss modification, 0 without
  ppo: ppo.PPOHyper  # the Top PPO's

  @classmethod
  def of(cls, top: TopConfig) -> "TopHyper":
    alpha = top.alpha if top.reward_mod else (0.0,) * len(top.alpha)
    return cls(alpha=_f32(alpha), s_o=_f32(top.s_o), s_o_start=_f32(top.s_o_start),
               s_e_weight=_f32(1.0 if top.loss_mod else 0.0), ppo=ppo.PPOHyper.of(top.ppo))


@struct.dataclass
class Hyper:
  """Every traced number of one lane (one variant)."""

  top: TopHyper
  rho: jax.Array  # () the homeostasis target rate (Ref:*)
  middle_goal_noise: jax.Array  # () std of the Gaussian noise on Middle TD3 goals
  low: td3.TD3Hyper  # learning rates, gamma, tau, noises of the Low TD3
  middle: td3.TD3Hyper  # and of the Middle TD3
  middle_ppo: ppo.PPOHyper  # learning rates, gamma, clip, coefficients of the Middle PPO


def _f32(x) -> np.ndarray:
  return np.asarray(x, np.float32)


def of(config: AgentConfig) -> Hyper:
  """The traced numbers of ``config``: compiled in as constants where closed over (the
  learners' as the Python floats they were before), leaves where passed."""
  return Hyper(top=TopHyper.of(config.top), rho=_f32(config.homeostasis.rho),
               middle_goal_noise=_f32(config.middle_goal_noise),
               low=td3.TD3Hyper.of(config.low), middle=td3.TD3Hyper.of(config.middle),
               middle_ppo=ppo.PPOHyper.of(config.middle_ppo))


def static_key(config: AgentConfig) -> AgentConfig:
  """``config`` with its traced fields normalised: equal keys, one program."""
  default = AgentConfig()
  return override(config, {path: get(default, path) for path in TRACED})


def stack(configs) -> Hyper:
  """The Hyper of each config stacked on a leading variant axis."""
  return jax.tree.map(lambda *xs: np.stack(xs).astype(np.float32), *[of(c) for c in configs])


def check_group(configs) -> AgentConfig:
  """The one static key of ``configs``; a ValueError naming the fields where they differ."""
  if not configs:
    raise ValueError("a group needs at least one config")
  key = static_key(configs[0])
  for i, c in enumerate(configs[1:], 1):
    other = static_key(c)
    if other != key:
      raise ValueError(f"variant {i} cannot share variant 0's program: they differ in "
                       f"{', '.join(differences(key, other))} (not traced)")
  return key
