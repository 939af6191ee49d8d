"""Ours' chooser (switch "top"): the Top level, a PPO over g_expl_mode in (TD3, PPO, RANDOM),
one choice per Top horizon. Its options are ``config.TopConfig`` (``AgentConfig.top``).

Per env, over a Top horizon of 50 steps run in mode m (the paper's Algorithm 1):

    R_m += R;  Done_m += success;  Count_m += 1                        (every env step)
    at the horizon's end:
      S_O_m   = Done_m / Count_m;   done_m = S_O_m >= S_O[m]          (S_O = 0.9 when starting)
      R_final = R_m + alpha[m] R_m                                    (alpha = 0 without reward mod)
      Top rollout <- ((s_0, target), m, log pi_T(m | s_0), R_final, done_m or episode end)
      m' ~ pi_T(s, target)         (forced to RANDOM in warm-up and in the starting mode)
    every 400 steps: Top PPO on the 8 latest Top transitions, per-sample loss weights
      1 + S_E for the explore modes, 1 - S_E for TD3 (1 without the loss modification)

R_m is the sum of task rewards; rewards are negative, so alpha > 0 penalises a mode ("larger
alpha, rarer mode"). The Top's rollout also ends at an episode's end (its Monte Carlo returns
never cross episodes), unless ``returns_cross_episodes`` (the paper's code: they end at done_m
only).

``Top`` is the level (``make_top``): a horizon's start, sums and close, and the Top PPO's
update. ``TopChooser`` is it as a chooser (``modes.ModeChooser``, ``make``): every env's
horizon, the rollout and the schedule.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import buffers, hierarchy, lanes, ppo
from nonmono_jax.core import metrics as metrics_lib
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.gates import gated
from nonmono_jax.core.lanes import Numbers
from nonmono_jax.core.modes import Decision

N_MODES = len(hierarchy.MODES)


# --- the Top's formulas (the paper's Algorithm 1) -----------------------------------------------

def success_ratio(done_count: jax.Array, count: jax.Array) -> jax.Array:
  """S_O_m = Done_m / Count_m (0 for an empty horizon)."""
  return jp.where(count > 0, done_count / jp.maximum(count, 1), 0.0)


def top_done(s_o_m: jax.Array, s_o: jax.Array, mode: jax.Array) -> jax.Array:
  """done_m = S_O_m >= S_O[mode], as 0/1."""
  return (s_o_m >= jp.asarray(s_o)[mode]).astype(jp.float32)


def modified_reward(r_m: jax.Array, alpha: jax.Array, mode: jax.Array) -> jax.Array:
  """R_final = R_m + alpha[mode] * R_m (Eq. 6 of the paper)."""
  return r_m + jp.asarray(alpha)[mode] * r_m


def loss_weights(modes: jax.Array, s_e: jax.Array, td3_mode: int = hierarchy.TD3) -> jax.Array:
  """Train_T's per-sample weights: ``1 - S_E`` in the TD3 mode, ``1 + S_E`` in the others."""
  return jp.where(jp.asarray(modes) == td3_mode, 1.0 - s_e, 1.0 + s_e)


# --- the level ---------------------------------------------------------------------------------

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
  every env's current ``Horizon`` (``TopState``)."""

  ppo: ppo.PPO
  config: AgentConfig  # its options: config.top, returns_cross_episodes
  obs_size: int
  target: jax.Array  # (3,) the task's target, part of the Top's input

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
    s_o_m = success_ratio(h.done_count, h.count)
    s_o_start = jp.broadcast_to(jp.asarray(hp.s_o_start, jp.float32), jp.shape(hp.s_o))
    done_m = top_done(s_o_m, jp.where(starting, s_o_start, hp.s_o), h.mode)
    r_final = modified_reward(h.reward, hp.reward_mod * hp.alpha, h.mode)
    done = ppo.terminal(done_m, episode_end, self.config.returns_cross_episodes)
    step = ppo.Rollout(obs=h.obs, action=h.mode, log_prob=h.log_prob, reward=r_final,
                       done=done)
    return step, {"s_o_m": s_o_m, "done_m": done_m, "r_final": r_final}

  def init_rollout(self) -> ppo.Rollout:
    """An empty Top rollout of one env (``rollout_length`` of ``close``'s steps)."""
    scalar = jax.ShapeDtypeStruct((), jp.float32)
    h = Horizon(obs=jax.ShapeDtypeStruct((self.obs_size + hierarchy.GOAL_SIZE,), jp.float32),
                mode=jax.ShapeDtypeStruct((), jp.int32), log_prob=scalar, reward=scalar,
                done_count=scalar, count=scalar)
    hp = lanes.of(self.config).top
    return buffers.template(lambda h: self.close(h, False, False, hp)[0], h,
                            lead=(self.config.top.rollout_length,))

  def update(self, state: ppo.PPOState, rollout: ppo.Rollout, s_e,
             hp: Numbers) -> tuple[ppo.PPOState, dict]:
    """Top PPO on the rollout, its loss weights 1 -+ w S_E (w = ``hp.loss_mod``: 1 with the
    loss modification, 0 without: weights of exactly 1)."""
    weights = loss_weights(rollout.action, hp.loss_mod * s_e)
    return self.ppo.update(state, rollout, None, weights, hp.ppo)


def make_top(obs_size: int, target, config: AgentConfig) -> Top:
  policy = ppo.make_ppo(obs_size + hierarchy.GOAL_SIZE, N_MODES, config.top.ppo)
  return Top(ppo=policy, config=config, obs_size=obs_size,
             target=jp.asarray(target, jp.float32))


# --- the chooser -------------------------------------------------------------------------------

@struct.dataclass
class TopState:
  """The Top PPO, its rollout (E, rollout_length) and every env's current horizon (E,)."""

  learner: ppo.PPOState
  rollout: ppo.Rollout
  horizon: Horizon

  def learner_params(self) -> dict:
    return {"top": self.learner.params}


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class TopChooser:
  """Ours: m ~ pi_T(s, target) per Top horizon; Top PPO every ``top.train_every`` steps."""

  top: Top
  num_envs: int
  live_from: int  # warm-up + top.starting_steps
  name = "top"
  starting_mode = hierarchy.RANDOM

  def _start(self, params, obs, key, forced) -> Horizon:
    keys = jax.random.split(key, self.num_envs)
    return jax.vmap(self.top.start, in_axes=(None, 0, 0, None))(params, obs, keys, forced)

  def init(self, keys, obs, middle_params) -> tuple[TopState, jax.Array]:
    learner = self.top.ppo.init(keys.top)
    horizon = self._start(learner.params, obs, keys.horizon, self.live_from > 0)
    rollout = jax.vmap(lambda _: self.top.init_rollout())(jp.arange(self.num_envs))
    return TopState(learner=learner, rollout=rollout, horizon=horizon), horizon.mode

  def accumulate(self, state: TopState, reward, success) -> TopState:
    return state.replace(horizon=jax.vmap(self.top.accumulate)(state.horizon, reward, success))

  def mode_probs(self, params, obs) -> jax.Array:
    """pi_T(m | s_0, target) per mode, averaged over the envs."""
    log_prob = lambda x, a: self.top.ppo.log_prob(params, x, a, None)
    per_env = lambda x: jp.exp(jax.vmap(lambda a: log_prob(x, a))(jp.arange(N_MODES)))
    return jax.vmap(per_env)(obs).mean(0)

  def decide(self, state: TopState, mode, d: Decision, keys, hp: Numbers):
    """At a horizon's end: the Top transition, and the Top picks the next g_expl_mode."""
    top = self.top
    H = top.config.top.horizon

    def end_horizon(operand):
      state, _ = operand
      tr, m = jax.vmap(top.close, in_axes=(0, None, None, None))(
          state.horizon, d.t + 1 - H < self.live_from, d.episode_end, hp.top)
      slot = (d.t // H) % top.config.top.rollout_length
      rollout = ppo.set_step(state.rollout, slot, tr)
      horizon = self._start(state.learner.params, d.obs, keys.horizon,
                            d.t + 1 < self.live_from)
      probs = self.mode_probs(state.learner.params, horizon.obs)
      m = {k: v.mean() for k, v in m.items()}
      m.update({f"p_{name}": probs[j] for j, name in enumerate(hierarchy.MODES)})
      return (state.replace(rollout=rollout, horizon=horizon), horizon.mode), m

    horizon_end = d.t % H == H - 1
    (state, mode), m = gated(horizon_end, end_horizon, (state, mode))
    return state, mode, metrics_lib.level("horizon", m, horizon_end)

  def update(self, state: TopState, t, live, s_e, hp: Numbers):
    every = self.top.config.top.train_every
    ran = live & (t % every == every - 1)

    def train(state):
      learner, m = self.top.update(state.learner, state.rollout, s_e, hp.top)
      return state.replace(learner=learner), m

    state, m = gated(ran, train, state)
    return state, metrics_lib.level("top", m, ran)


def make(config: AgentConfig, obs_size: int, target, value) -> TopChooser:
  return TopChooser(top=make_top(obs_size, target, config), num_envs=config.num_envs,
                    live_from=config.warmup_steps + config.top.starting_steps)
