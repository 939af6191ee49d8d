"""PPO for the Middle level (Gaussian goals) and the Top level (3 modes), as pure functions.

Follows the PyTorch port the paper builds on (nikhilbarhate99/PPO-PyTorch, ``PPO.update``).
One update, over a rollout of N transitions (N = 3 at the Middle, 8 at the Top):

    R_t = r_t + gamma * R_{t+1} * (1 - d_t),   R_N = r_N      # Monte Carlo, reset at done
    R   = (R - mean(R)) / (std(R) + 1e-7)                     # over the rollout
    repeat K times:                                           # full batch, one Adam step each
      rho_t = exp(log pi_theta(a_t | s_t) - log pi_old(a_t | s_t))
      A_t   = R_t - sg(V_phi(s_t))
      l_t   = -min(rho_t A_t, clip(rho_t, 1 - eps, 1 + eps) A_t)
              + c_v (V_phi(s_t) - R_t)^2 - c_e H[pi_theta(. | s_t)]
      theta, phi <- Adam(grad mean_t(w_t l_t))                # lr_actor on theta, lr_critic on phi

``w_t`` is 1 except at the Top, where Algorithm 1's Train_T sets ``l + S_E l`` in the
exploration modes and ``l - S_E l`` in the TD3 mode (``modes.top.loss_weights``). Note that
Adam is invariant to a uniform rescaling of the loss: the weights change an update only where
they differ between samples. ``value_weighting`` says what the weight multiplies of the value term:
the sample's own ``c_v (V_phi(s_t) - R_t)^2`` (``"sample"``), or the rollout's mean value loss
``c_v mean_j (V_phi(s_j) - R_j)^2``, which the paper's code (``PPOM.train``) adds to every
sample's loss before weighting it (``"batch"``); with weights of 1 the two are the same.

Kept from the port: full-batch epochs (no minibatches), normalised Monte Carlo returns that
do not bootstrap past the rollout's end, no GAE, no advantage normalisation, no gradient
clipping, the advantage against the current critic without gradient, torch's unbiased std
(``ddof=1``) in the normalisation, tanh MLPs, a state-independent Gaussian std decayed by the
caller (``gaussian_std``) and the Adam parameter groups. The Gaussian head is the port's
(``mean_head="linear"``): a linear (unbounded) mean and the std in action units, so the
Middle's std of 0.6 is 0.6 goal units, as in the paper's code (the caller clips the goal to
its range). ``mean_head="tanh"`` keeps this project's earlier head, ``action_scale *
tanh(mlp)`` with std ``std * action_scale`` per dimension (at a goal range of 10 an x/y std
of 6: about as entropic as uniform random goals). Networks are initialised as ``init`` says
(``networks.INITS``: ``"torch"`` is the port's).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import flax.linen as nn
import jax
import jax.numpy as jp
import optax
from flax import struct

from nonmono_jax.core import learning, networks
# declared with the agent's config, which imports no JAX
from nonmono_jax.core.config import MEAN_HEADS, PPOConfig  # noqa: F401
from nonmono_jax.core.lanes import Numbers

_RETURN_EPS = 1e-7  # the port's normaliser epsilon
_LOG_2PI_E = math.log(2.0 * math.pi * math.e)


@struct.dataclass
class PPOState:
  """Learner state: ``params = {'actor': ..., 'critic': ...}`` and Adam's state."""

  params: dict
  opt_state: optax.OptState


@struct.dataclass
class Rollout:
  """N transitions in time order; ``action`` is (N, A) float (Gaussian) or (N,) int (discrete).

  Several envs' rollouts stack on a leading axis: (E, N, ...), returns computed per env.
  """

  obs: jax.Array  # (N, obs_size)
  action: jax.Array
  log_prob: jax.Array  # (N,) log pi_old(a | s), from ``act`` at collection time
  reward: jax.Array  # (N,)
  done: jax.Array  # (N,) 1 where the episode ended after this transition


@dataclasses.dataclass(frozen=True)
class PPO:
  """One PPO learner's pure functions (``make_ppo``); the discrete head ignores ``std``."""

  config: PPOConfig
  obs_size: int
  action_size: int
  action_scale: jax.Array
  init: Callable[[jax.Array], PPOState]
  act: Callable[..., tuple[jax.Array, jax.Array]]  # (params, obs, key, std) -> (a, logp)
  mode: Callable[..., jax.Array]  # (params, obs) -> greedy action
  log_prob: Callable[..., jax.Array]  # (params, obs, action, std) -> logp
  entropy: Callable[..., jax.Array]  # (params, obs, std) -> H
  value: Callable[..., jax.Array]  # (params, obs) -> V
  per_sample_loss: Callable[..., tuple[jax.Array, dict]]  # (params, batch, std)
  loss: Callable[..., tuple[jax.Array, dict]]  # (params, batch, std, loss_weights)
  update: Callable[..., tuple[PPOState, dict]]  # (state, batch, std, loss_weights=None)


def gaussian_std(step: jax.Array, config: PPOConfig) -> jax.Array:
  """The port's std schedule: ``std_init - std_decay`` per ``std_decay_every`` steps, floored;
  with ``decay_at_start`` the first decay falls at step 0 (the paper's code)."""
  n = jp.floor_divide(jp.asarray(step), config.std_decay_every).astype(jp.float32)
  if config.decay_at_start:
    n = n + 1.0
  std = jp.round(config.std_init - config.std_decay * n, 4)
  return jp.maximum(std, config.std_min).astype(jp.float32)


def monte_carlo_returns(rewards: jax.Array, dones: jax.Array, gamma: float,
                        normalize: bool = True) -> jax.Array:
  """Discounted returns along the last (time) axis, reset at dones, not bootstrapped at the end.

  Leading axes are independent rollouts (several envs); the normalisation, on by default, runs
  over all of them together.
  """
  rewards = jp.asarray(rewards, jp.float32)
  dones = jp.asarray(dones).astype(jp.float32)

  def step(g, rd):
    r, d = rd
    g = r + gamma * g * (1.0 - d)
    return g, g

  time_first = lambda x: jp.moveaxis(x, -1, 0)
  _, returns = jax.lax.scan(step, jp.zeros(rewards.shape[:-1], jp.float32),
                            (time_first(rewards), time_first(dones)), reverse=True)
  returns = jp.moveaxis(returns, 0, -1)
  if normalize:
    returns = (returns - returns.mean()) / (returns.std(ddof=1) + _RETURN_EPS)
  return returns


def set_step(rollouts: Rollout, slot, steps: Rollout) -> Rollout:
  """Every env's rollout (E, T) with its step ``slot`` set to ``steps`` (E,)."""
  return jax.tree.map(lambda r, x: r.at[:, slot].set(x), rollouts, steps)


def terminal(done, episode_end, returns_cross_episodes: bool) -> jax.Array:
  """A rollout step's terminal: its own ``done``, or the episode's end, so that Monte Carlo
  returns never cross episodes, unless ``returns_cross_episodes`` (the paper's code: its
  returns end at their own terminals only)."""
  ends_returns = 0.0 if returns_cross_episodes else 1.0
  return jp.maximum(done, ends_returns * jp.asarray(episode_end, jp.float32))


def make_ppo(obs_size: int, action_size: int, config: PPOConfig = PPOConfig(),
             action_scale: jax.Array | None = None) -> PPO:
  """Builds the PPO functions for a Gaussian (default) or categorical (``config.discrete``) head."""
  discrete = config.discrete
  if discrete and action_scale is not None:
    raise ValueError("action_scale applies to the Gaussian head only")
  if action_scale is None:
    action_scale = jp.ones((action_size,), jp.float32)
  action_scale = jp.broadcast_to(jp.asarray(action_scale, jp.float32), (action_size,))
  # A dimension with scale 0 (a goal range of 0, e.g. z for the point robot) is fixed at 0:
  # it has no distribution and adds nothing to log-probabilities or the entropy.
  active = action_scale > 0
  n_active = int(jp.sum(active)) if not discrete else action_size
  scaled = config.mean_head == "tanh"
  # sigma = std * unit per dimension: the action range for the tanh head, 1 for the linear one
  unit = jp.where(active, action_scale, 1.0) if scaled else jp.ones((action_size,), jp.float32)
  log_unit_sum = jp.sum(jp.where(active, jp.log(unit), 0.0))

  actor = networks.make_mlp(obs_size, config.hidden, action_size, activation=nn.tanh,
                            final_activation=nn.tanh if scaled and not discrete else None,
                            init=config.init)
  critic = networks.make_mlp(obs_size, config.hidden, 1, activation=nn.tanh, init=config.init)
  optimizer = optax.multi_transform(
      {"actor": optax.adam(1.0), "critic": optax.adam(1.0)},  # rates: learning.gradient_step
      lambda p: {k: jax.tree.map(lambda _: k, v) for k, v in p.items()})

  def init(key):
    k_actor, k_critic = jax.random.split(key)
    params = {"actor": actor.init(k_actor), "critic": critic.init(k_critic)}
    return PPOState(params=params, opt_state=optimizer.init(params))

  def _head(params, obs):
    """Logits (discrete) or the Gaussian mean (linear, or ``action_scale * tanh``)."""
    out = actor.apply(params["actor"], obs)
    return out * action_scale if scaled and not discrete else out

  def _gaussian_log_prob(mean, action, std):
    sigma = std * unit
    z = (action - mean) / sigma
    per_dim = jp.where(active, -0.5 * z**2 - jp.log(sigma), 0.0)
    return jp.sum(per_dim, axis=-1) - 0.5 * n_active * math.log(2 * jp.pi)

  def log_prob(params, obs, action, std):
    head = _head(params, obs)
    if discrete:
      logp = jax.nn.log_softmax(head)
      return jp.take_along_axis(logp, action[..., None].astype(jp.int32), axis=-1)[..., 0]
    return _gaussian_log_prob(head, action, std)

  def entropy(params, obs, std):
    head = _head(params, obs)
    if discrete:
      logp = jax.nn.log_softmax(head)
      return -jp.sum(jp.exp(logp) * logp, axis=-1)
    h = 0.5 * n_active * _LOG_2PI_E + n_active * jp.log(std) + log_unit_sum
    return jp.broadcast_to(h, head.shape[:-1])

  def act(params, obs, key, std):
    head = _head(params, obs)
    if discrete:
      action = jax.random.categorical(key, head, axis=-1)
      logp = jp.take_along_axis(jax.nn.log_softmax(head), action[..., None], axis=-1)[..., 0]
      return action, logp
    noise = std * unit * jax.random.normal(key, head.shape)
    action = jp.where(active, head + noise, 0.0)
    return action, _gaussian_log_prob(head, action, std)

  def mode(params, obs):
    head = _head(params, obs)
    return jp.argmax(head, axis=-1) if discrete else jp.where(active, head, 0.0)

  def value(params, obs):
    return critic.apply(params["critic"], obs)[..., 0]

  def per_sample_loss(params, batch: Rollout, std, hp: Numbers):
    returns = monte_carlo_returns(batch.reward, batch.done, hp.gamma)
    logp = log_prob(params, batch.obs, batch.action, std)
    v = value(params, batch.obs)
    ent = entropy(params, batch.obs, std)
    adv = returns - jax.lax.stop_gradient(v)
    log_ratio = logp - batch.log_prob
    ratio = jp.exp(log_ratio)
    surrogate = jp.minimum(ratio * adv, jp.clip(ratio, 1 - hp.clip, 1 + hp.clip) * adv)
    value_err = (v - returns) ** 2
    value_term = value_err if config.value_weighting == "sample" else value_err.mean()
    loss = -surrogate + hp.value_coef * value_term - hp.entropy_coef * ent
    metrics = {
        "policy_loss": -surrogate.mean(),
        "value_loss": value_err.mean(),
        "entropy": ent.mean(),
        "approx_kl": jax.lax.stop_gradient(((ratio - 1) - log_ratio).mean()),
        "clip_fraction": (jp.abs(ratio - 1) > hp.clip).astype(jp.float32).mean(),
    }
    return loss, metrics

  def loss(params, batch: Rollout, std, loss_weights, hp: Numbers):
    per_sample, metrics = per_sample_loss(params, batch, std, hp)
    total = jp.mean(loss_weights * per_sample)
    return total, {"loss": total, **metrics}

  def update(state: PPOState, batch: Rollout, std, loss_weights, hp: Numbers):
    """K epochs on the rollout, each sample's loss times its ``loss_weights``; ``hp`` the
    lane's numbers (``lanes.of(config)``: rates, gamma, clip, coefficients)."""
    rates = {"actor": hp.lr_actor, "critic": hp.lr_critic}

    def epoch(carry, _):
      params, opt_state, metrics = learning.gradient_step(
          loss, optimizer, *carry, batch, std, loss_weights, hp, lr=rates)
      return (params, opt_state), metrics

    (params, opt_state), metrics = jax.lax.scan(
        epoch, (state.params, state.opt_state), None, length=config.k_epochs)
    metrics = jax.tree.map(jp.mean, metrics)  # averaged over the K epochs
    return state.replace(params=params, opt_state=opt_state), metrics

  return PPO(config=config, obs_size=obs_size, action_size=action_size,
             action_scale=action_scale, init=init, act=act, mode=mode, log_prob=log_prob,
             entropy=entropy, value=value, per_sample_loss=per_sample_loss, loss=loss,
             update=update)
