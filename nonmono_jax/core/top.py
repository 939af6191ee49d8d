"""The Top level: PPO over g_expl_mode in (TD3, PPO, RANDOM), one choice per Top horizon.

Per env, over a Top horizon of 50 steps run in mode m (the paper's Algorithm 1):

    R_m += R;  Done_m += success;  Count_m += 1                        (every env step)
    at the horizon's end:
      S_O_m   = Done_m / Count_m;   done_m = S_O_m >= S_O[m]          (S_O = 0.9 when starting)
      R_final = R_m + alpha[m] R_m                                    (alpha = 0 without reward mod)
      Top rollout <- ((s_0, target), m, log pi_T(m | s_0), R_final, done_m or episode end)
      m' ~ pi_T(s, target)         (forced to RANDOM in warm-up and in the starting mode)
    every 400 steps: Top PPO on the 8 latest Top transitions, per-sample loss weights
      1 + S_E for the explore modes, 1 - S_E for TD3 (1 without the loss modification)

The Top's rollout also ends at an episode's end (its Monte Carlo returns never cross episodes),
unless ``returns_cross_episodes`` (the paper's code: they end at done_m only).
"""

from __future__ import annotations

import dataclasses
import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import buffers, hierarchy, lanes, ppo
from nonmono_jax.core.config import TopConfig
from nonmono_jax.core.lanes import Numbers


@struct.dataclass
class Horizon:
  """One env's current Top horizon: where it started, its mode and its running sums."""

  obs: jax.Array  # (obs + 3,) Top input (s_0, target)
  mode: jax.Array  # int32 g_expl_mode
  log_prob: jax.Array  # log pi_T(mode | s_0, target)
  reward: jax.Array  # R_m
  done_count: jax.Array  # Done_m
  count: jax.Array  # Count_m


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class Top:
  """The Top's functions (``make_top`` builds it); its state is the Top PPO's, a rollout and
  every env's current ``Horizon`` (``modes.TopState``)."""

  ppo: ppo.PPO
  config: TopConfig
  obs_size: int
  target: jax.Array  # (3,) the task's target, part of the Top's input
  returns_cross_episodes: bool = False  # the paper's code: returns end at done_m only

  def start(self, params, obs, key, forced) -> Horizon:
    """A new horizon from s: m ~ pi_T(s, target), or RANDOM where ``forced``."""
    x = jp.concatenate([obs, self.target])
    sampled, _ = self.ppo.act(params, x, key, None)
    mode = jp.where(forced, hierarchy.RANDOM, sampled).astype(jp.int32)
    zero = jp.zeros(())
    return Horizon(obs=x, mode=mode, log_prob=self.ppo.log_prob(params, x, mode, None),
                   reward=zero, done_count=zero, count=zero)

  def accumulate(self, h: Horizon, reward, success) -> Horizon:
    return h.replace(reward=h.reward + reward, done_count=h.done_count + success,
                     count=h.count + 1)

  def close(self, h: Horizon, starting, episode_end, hp: Numbers) -> tuple[ppo.Rollout, dict]:
    """The Top transition of a finished horizon (``starting``: the starting mode's S_O);
    ``hp`` the Top's numbers (alpha, its switch ``reward_mod``: 0 or 1, S_O)."""
    s_o_m = hierarchy.success_ratio(h.done_count, h.count)
    s_o_start = jp.broadcast_to(jp.asarray(hp.s_o_start, jp.float32), jp.shape(hp.s_o))
    done_m = hierarchy.top_done(s_o_m, jp.where(starting, s_o_start, hp.s_o), h.mode)
    r_final = hierarchy.modified_reward(h.reward, hp.reward_mod * hp.alpha, h.mode)
    ends_returns = 0.0 if self.returns_cross_episodes else 1.0
    done = jp.maximum(done_m, ends_returns * jp.asarray(episode_end, jp.float32))
    step = ppo.Rollout(obs=h.obs, action=h.mode, log_prob=h.log_prob, reward=r_final,
                       done=done)
    return step, {"s_o_m": s_o_m, "done_m": done_m, "r_final": r_final}

  def init_rollout(self) -> ppo.Rollout:
    """An empty Top rollout of one env (``rollout_length`` of ``close``'s steps)."""
    scalar = jax.ShapeDtypeStruct((), jp.float32)
    h = Horizon(obs=jax.ShapeDtypeStruct((self.obs_size + hierarchy.GOAL_SIZE,), jp.float32),
                mode=jax.ShapeDtypeStruct((), jp.int32), log_prob=scalar, reward=scalar,
                done_count=scalar, count=scalar)
    hp = lanes.of(self.config)
    return buffers.template(lambda h: self.close(h, False, False, hp)[0], h,
                            lead=(self.config.rollout_length,))

  def update(self, state: ppo.PPOState, rollout: ppo.Rollout, s_e,
             hp: Numbers) -> tuple[ppo.PPOState, dict]:
    """Top PPO on the rollout, its loss weights 1 -+ w S_E (w = ``hp.loss_mod``: 1 with the
    loss modification, 0 without: weights of exactly 1)."""
    weights = ppo.top_loss_weights(rollout.action, hp.loss_mod * s_e, hierarchy.TD3)
    return self.ppo.update(state, rollout, None, weights, hp.ppo)


def make_top(obs_size: int, target, config: TopConfig,
             returns_cross_episodes: bool = False) -> Top:
  policy = ppo.make_ppo(obs_size + hierarchy.GOAL_SIZE, len(hierarchy.MODES), config.ppo)
  return Top(ppo=policy, config=config, obs_size=obs_size,
             target=jp.asarray(target, jp.float32),
             returns_cross_episodes=returns_cross_episodes)
