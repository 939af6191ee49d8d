"""The Low level: a goal-conditioned TD3 that acts every env step (HIRO).

    a   = clip(pi_L(s, g) + N(0, sigma_L), +-limit)       (uniform random during warm-up)
    g'  = s[:3] + g - s'[:3];   r_L = -||g'||;   done_L = ||g'|| <= 1.5
    Low buffer <- (s, g, a, r_L, s', g', done_L);  ``updates`` TD3 updates per env step

``low_done_goal="current"`` tests the goal of the step instead, ||g|| <= 1.5 (the paper's code:
"s was already within 1.5 of its subgoal"). Its options: ``AgentConfig.low`` (its TD3),
``low_updates`` and ``low_done_goal``.
"""

from __future__ import annotations

import dataclasses
import jax
import jax.numpy as jp

from nonmono_jax.core import buffers, hierarchy, learning, td3
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import Numbers


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class Low:
  """The Low's functions (``make_low`` builds it); its state is a ``td3.TD3State`` and a
  ``buffers.ReplayBuffer`` of ``td3.Transition``s in the agent's ``SeedState``."""

  td3: td3.TD3
  config: AgentConfig
  obs_size: int
  action_size: int
  limit: jax.Array  # (action_size,) the torque (or velocity) limit

  def act(self, params: td3.TD3Params, obs, goal, key, warm, hp: Numbers) -> jax.Array:
    """The behaviour action: uniform during warm-up, else pi_L plus Gaussian noise (std
    ``hp.expl_noise``)."""
    k1, k2 = jax.random.split(key)
    random = jax.random.uniform(k1, (self.action_size,), minval=-self.limit, maxval=self.limit)
    return jp.where(warm, random, self.td3.explore(params, obs, goal, k2, hp.expl_noise))

  def transition(self, s, g, a, s_next) -> td3.Transition:
    """(s, g, a, r_L, s', g', done_L) of one env step."""
    g_next = hierarchy.goal_transition(s, g, s_next)
    return td3.Transition(obs=s, context=g, action=a,
                          reward=hierarchy.low_reward(s, g, s_next), next_obs=s_next,
                          next_context=g_next,
                          done=hierarchy.low_done(g_next if self.config.low_done_goal == "next"
                                                  else g))

  def update(self, state: td3.TD3State, buffer: buffers.ReplayBuffer, key, t,
             hp: Numbers) -> tuple[td3.TD3State, dict]:
    """``low_updates`` TD3 updates on batches from the Low buffer; metrics of the last."""
    config, updates = self.config.low, self.config.low_updates

    def one(state, i):
      kb, ku = jax.random.split(jax.random.fold_in(key, i))
      batch = buffers.sample(buffer, kb, config.batch_size)
      n = t * updates + i  # the update counter: the delayed actor's clock
      return self.td3.update(state, batch, ku, n % config.policy_delay == 0, hp)

    return learning.repeat(one, state, updates)

  def init_buffer(self) -> buffers.ReplayBuffer:
    vec = lambda n: jax.ShapeDtypeStruct((n,), jp.float32)
    n = self.obs_size
    example = jax.eval_shape(self.transition, vec(n), vec(hierarchy.GOAL_SIZE),
                             vec(self.action_size), vec(n))
    return buffers.init(example, self.config.low.buffer_size)


def make_low(obs_size: int, action_size: int, action_limit, config: AgentConfig) -> Low:
  learner = td3.make_td3(obs_size, hierarchy.GOAL_SIZE, action_size, action_limit, config.low)
  lim = jp.broadcast_to(jp.asarray(action_limit, jp.float32), (action_size,))
  return Low(td3=learner, config=config, obs_size=obs_size, action_size=action_size, limit=lim)
