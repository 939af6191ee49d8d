"""TD3 (Fujimoto et al. 2018), goal- or context-conditioned, as both levels of HIRO use it.

    for each update (batch of (s, g, a, r, s', g', d) from the replay buffer):
      a' = clip(pi_targ(s', g') + clip(N(0, sigma), -c, c), -scale, scale)   (target smoothing)
      y  = r + gamma * (1 - d) * min(Q1_targ, Q2_targ)(s', g', a')
      critic: minimise (Q1(s, g, a) - y)^2 + (Q2(s, g, a) - y)^2
      every ``policy_delay`` updates:
        actor: maximise Q1(s, g, pi(s, g))
        targets: theta_targ <- tau * theta + (1 - tau) * theta_targ      (Polyak)

The context ``g`` is the Low level's goal or the Middle level's target position; the networks
take ``concat(s, g[, a])``. The delayed actor step is gated by an argument that the trainer
derives from its unbatched step counter, so under ``vmap`` over seeds it stays a real
``lax.cond`` branch (docs/spec.md, section 6). In ours the Middle TD3 uses no target smoothing
(``target_smoothing=False``); HIRO keeps it. The smoothing noise is drawn per sample (TD3's,
``target_noise="sample"``) or once per batch, one vector shared by every sample
(``"batch"``: the paper's code, ``hiro.step_update_l``).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import flax.linen as nn
import jax
import jax.numpy as jp
import optax
from flax import struct

from nonmono_jax.core import learning, networks
# declared with the agent's config, which imports no JAX
from nonmono_jax.core.config import TD3Config  # noqa: F401
from nonmono_jax.core.lanes import Numbers


@struct.dataclass
class Transition:
  """One transition (or a batch of them): obs, context, action, reward, next, done."""

  obs: jax.Array
  context: jax.Array
  action: jax.Array
  reward: jax.Array
  next_obs: jax.Array
  next_context: jax.Array
  done: jax.Array  # 1.0 where the bootstrap is cut


@struct.dataclass
class TD3Params:
  actor: dict
  critic: dict  # twin critics, stacked on a leading axis of 2
  target_actor: dict
  target_critic: dict


@struct.dataclass
class TD3State:
  params: TD3Params
  actor_opt: optax.OptState
  critic_opt: optax.OptState


def td_target(reward, done, q1_next, q2_next, gamma):
  """Clipped double-Q target: r + gamma (1 - d) min(Q1', Q2')."""
  return reward + gamma * (1.0 - done) * jp.minimum(q1_next, q2_next)


def polyak(target, online, tau):
  """theta_targ <- tau theta + (1 - tau) theta_targ."""
  return jax.tree.map(lambda t, o: (1.0 - tau) * t + tau * o, target, online)


@dataclasses.dataclass(frozen=True)
class TD3:
  """The pure functions of one TD3 learner (built by ``make_td3``)."""

  config: TD3Config
  action_scale: jax.Array
  init: Callable[[jax.Array], TD3State]
  act: Callable[..., jax.Array]
  explore: Callable[..., jax.Array]
  q_values: Callable[..., jax.Array]
  critic_loss: Callable[..., tuple]
  actor_loss: Callable[..., tuple]
  update: Callable[..., tuple]


def make_td3(obs_size: int, context_size: int, action_size: int, action_scale,
             config: TD3Config = TD3Config()) -> TD3:
  """Build TD3 for observations, a context (goal) and actions in [-scale, scale]."""
  scale = jp.broadcast_to(jp.asarray(action_scale, jp.float32), (action_size,))
  actor_net = networks.make_mlp(obs_size + context_size, config.hidden, action_size,
                                activation=nn.relu, final_activation=jp.tanh, init=config.init)
  critic_net = networks.make_mlp(obs_size + context_size + action_size, config.hidden, 1,
                                 activation=nn.relu, init=config.init)
  actor_opt = optax.adam(1.0)  # the learning rates scale the updates (learning.gradient_step)
  critic_opt = optax.adam(1.0)

  def pi(actor_params, obs, context):
    return scale * actor_net.apply(actor_params, obs, context)

  def q_values(critic_params, obs, context, action):
    """(2, ...) twin Q-values."""
    return jax.vmap(lambda p: critic_net.apply(p, obs, context, action)[..., 0])(critic_params)

  def init(key):
    ka, kc = jax.random.split(key)
    actor = actor_net.init(ka)
    critic = jax.vmap(critic_net.init)(jax.random.split(kc, 2))
    params = TD3Params(actor=actor, critic=critic, target_actor=actor, target_critic=critic)
    return TD3State(params=params, actor_opt=actor_opt.init(actor),
                    critic_opt=critic_opt.init(critic))

  def act(params: TD3Params, obs, context):
    return pi(params.actor, obs, context)

  def explore(params: TD3Params, obs, context, key, noise_std):
    a = pi(params.actor, obs, context)
    return jp.clip(a + noise_std * jax.random.normal(key, a.shape), -scale, scale)

  def critic_loss(critic_params, params: TD3Params, batch: Transition, key, hp: Numbers):
    a_next = pi(params.target_actor, batch.next_obs, batch.next_context)
    if config.target_smoothing:
      shape = a_next.shape if config.target_noise == "sample" else a_next.shape[-1:]
      noise = jp.clip(hp.policy_noise * jax.random.normal(key, shape),
                      -hp.noise_clip, hp.noise_clip)
      a_next = jp.clip(a_next + noise, -scale, scale)
    q_next = q_values(params.target_critic, batch.next_obs, batch.next_context, a_next)
    y = jax.lax.stop_gradient(
        td_target(batch.reward, batch.done, q_next[0], q_next[1], hp.gamma))
    q = q_values(critic_params, batch.obs, batch.context, batch.action)
    loss = jp.mean((q[0] - y) ** 2) + jp.mean((q[1] - y) ** 2)
    return loss, {"critic_loss": loss, "q": jp.mean(q[0]), "target_q": jp.mean(y)}

  def actor_loss(actor_params, params: TD3Params, batch: Transition):
    a = pi(actor_params, batch.obs, batch.context)
    # Q1 alone (TD3's actor follows the first critic): the twin pair's second half would be
    # computed forward and backward for nothing
    critic_1 = jax.tree.map(lambda x: x[0], params.critic)
    q1 = critic_net.apply(critic_1, batch.obs, batch.context, a)[..., 0]
    loss = -jp.mean(q1)
    return loss, {"actor_loss": loss}

  def update(state: TD3State, batch: Transition, key, update_actor, hp: Numbers):
    """One critic step; the actor step and Polyak targets when ``update_actor``; ``hp`` the
    lane's numbers (``lanes.of(config)``: rates, gamma, tau, noises).

    ``update_actor`` should be unbatched (from the trainer's step counter) so that under
    ``vmap`` over seeds the ``lax.cond`` stays a branch rather than a select.
    """
    p = state.params
    critic, critic_opt_state, cm = learning.gradient_step(
        critic_loss, critic_opt, p.critic, state.critic_opt, p, batch, key, hp,
        lr=hp.lr_critic)
    p = p.replace(critic=critic)

    def actor_step(written):  # only what it writes goes through the cond (gates.py)
      actor, target_actor, target_critic, actor_opt_state = written
      actor, opt, am = learning.gradient_step(actor_loss, actor_opt, actor, actor_opt_state,
                                              p, batch, lr=hp.lr_actor)
      return ((actor, polyak(target_actor, actor, hp.tau),
               polyak(target_critic, p.critic, hp.tau), opt), am["actor_loss"])

    def skip(written):
      return written, jp.zeros((), jp.float32)

    written = (p.actor, p.target_actor, p.target_critic, state.actor_opt)
    (actor, target_actor, target_critic, opt), a_loss = jax.lax.cond(
        update_actor, actor_step, skip, written)
    state = state.replace(params=p.replace(actor=actor, target_actor=target_actor,
                                           target_critic=target_critic),
                          critic_opt=critic_opt_state, actor_opt=opt)
    return state, {**cm, "actor_loss": a_loss}

  return TD3(config=config, action_scale=scale, init=init, act=act, explore=explore,
             q_values=q_values, critic_loss=critic_loss, actor_loss=actor_loss, update=update)
