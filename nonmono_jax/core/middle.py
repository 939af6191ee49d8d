"""The Middle level: three sub-policies that emit a goal every c steps, and their learners.

g_expl_mode picks which one emits the next goal (a relative xyz offset within +-goal_range):

    TD3     g = clip(pi_M(s, target) + N(0, sigma_M))     sigma_M: HIRO 1, ours 0
            (pi_M(s) with ``middle_td3_input="state"``, the paper's code; its critic Q(s, g))
    PPO     g = clip(N(mu_M(s, target), std_t))          std_t decays 0.6 -> 0.1 (goal units)
    RANDOM  g ~ U(-range, range)                          (or the paper code's clip(randn*range))

Every Middle transition (s_0, target, g, R_M = 0.1 sum R, s_c, done = success at s_c),
whichever mode chose g, feeds both learners:

- the Middle TD3 buffer, with g relabelled by HIRO's off-policy correction. The paper's code
  relabels once, when the segment is stored, under the Low's target actor
  (``middle_relabel="store"``); the original HIRO relabels every sampled batch under the
  current Low actor (``"sample"``: the buffer then keeps the segment's states and actions).
- the Middle PPO rollout. In the paper's code PPO samples its own goal at every Middle
  decision and stores that sample, with its log-probability, next to the executed segment's
  reward, whichever mode chose the executed goal (``middle_ppo_sample="own"``);
  ``"executed"`` stores the executed goal g with log pi_PPO(g | s_0) instead. Its terminal is
  success at s_c, or the episode's end (so Monte Carlo returns never cross episodes) unless
  ``returns_cross_episodes`` (the paper's code: success only).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jp
from flax import struct

from nonmono_jax.core import buffers, hierarchy, learning, ppo, relabel, td3
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import Numbers


@struct.dataclass
class Segment:
  """The low steps under one Middle goal, for the Middle transition and relabelling."""

  obs: jax.Array  # (c + 1, obs): s_0 .. s_c
  actions: jax.Array  # (c, action)
  rewards: jax.Array  # (c,) task rewards
  success: jax.Array  # () 1.0 where s_c is within the success radius (done of the Middle)
  goal: jax.Array  # (3,) the goal emitted at s_0
  ppo_action: jax.Array  # (3,) the Middle PPO's action stored for this segment
  log_prob: jax.Array  # () log pi_PPO(ppo_action | s_0, target), for the Middle PPO


@struct.dataclass
class MiddlePPOState:
  """The Middle PPO's learner and its rollout, (E, middle_ppo_every / c) per seed."""

  learner: ppo.PPOState
  rollout: ppo.Rollout

  def learner_params(self) -> dict:
    return {"middle_ppo": self.learner.params}


@struct.dataclass
class NoMiddlePPOState:
  """The Middle PPO of a method without one (HIRO, Ref:Uniform): nothing."""

  def learner_params(self) -> dict:
    return {}


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class MiddlePPO:
  """The Middle PPO as a sub-policy (``make_middle`` builds it): its goal proposals, what it
  stores of a segment, its learning. ``NoMiddlePPO`` is the same for a method without one."""

  learner: ppo.PPO
  config: AgentConfig
  trains = True

  def std(self, t):
    return ppo.gaussian_std(t, self.config.middle_ppo)

  def init(self, key, rollout: ppo.Rollout) -> MiddlePPOState:
    """The learner (from ``key``) and the empty ``rollout`` (E, middle_ppo_every / c)."""
    return MiddlePPOState(learner=self.learner.init(key), rollout=rollout)

  def params(self, state: MiddlePPOState):
    return state.learner.params

  def propose(self, params, obs, key, t):
    """(its sample, log pi of it) at (s, target)."""
    return self.learner.act(params, obs, key, self.std(t))

  def stored(self, params, obs, g, proposal, t):
    """(action, log pi) the rollout keeps for a segment that ran goal g: PPO's own sample
    ("own", the paper's code) or g ("executed")."""
    if self.config.middle_ppo_sample == "own":
      return proposal
    return g, self.learner.log_prob(params, obs, g, self.std(t))

  def store(self, state: MiddlePPOState, t, steps) -> MiddlePPOState:
    """The segments' PPO steps (E, ...) into their rollout slot, the segment ending at t."""
    slot = (t // self.config.c) % self.config.middle_rollout_length
    return state.replace(rollout=ppo.set_step(state.rollout, slot, steps))

  def update(self, state: MiddlePPOState, t, hp: Numbers):
    """One update on the rollout, at the std of step t (reported as ``std``); ``hp`` the
    Middle PPO's numbers."""
    std = self.std(t)
    weights = jp.ones(state.rollout.reward.shape, jp.float32)
    new, m = self.learner.update(state.learner, state.rollout, std, weights, hp)
    return state.replace(learner=new), {**m, "std": std}


@dataclasses.dataclass(frozen=True)
class NoMiddlePPO:
  """No Middle PPO: proposes nothing any mode would take, stores and learns nothing."""

  trains = False

  def std(self, t):
    return jp.zeros(())

  def init(self, key, rollout) -> NoMiddlePPOState:
    return NoMiddlePPOState()

  def params(self, state):
    return None

  def propose(self, params, obs, key, t):
    return jp.zeros(hierarchy.GOAL_SIZE), jp.zeros(())

  def stored(self, params, obs, g, proposal, t):
    return g, jp.zeros(())

  def store(self, state, t, steps):
    return state

  def update(self, state, t, hp: Numbers):
    return state, {}


@dataclasses.dataclass(frozen=True, eq=False)  # identity: it holds arrays
class Middle:
  """The Middle's functions (``make_middle`` builds it): goals from the three sub-policies,
  segments, the Middle TD3 and its buffer; the Middle PPO is ``ppo``."""

  config: AgentConfig
  td3: td3.TD3
  ppo: MiddlePPO | NoMiddlePPO  # the Middle PPO, or NoMiddlePPO where the method has none
  obs_size: int
  action_size: int
  target: jax.Array  # (3,) the task's target
  goal_range: jax.Array  # (3,) goals within +-goal_range
  context: jax.Array  # what the Middle TD3 sees besides s: the target, or (0,) (paper's code)
  low_act: Callable[..., jax.Array]  # the Low's noiseless actor (params, obs, goal) -> a

  def random_goal(self, key, kind: str) -> jax.Array:
    """A goal U(+-range) (``kind="uniform"``) or clip(N(0, 1) * range) (``"gaussian"``)."""
    k, r = hierarchy.GOAL_SIZE, self.goal_range
    if kind == "uniform":
      return jax.random.uniform(key, (k,), minval=-r, maxval=r)
    return jp.clip(jax.random.normal(key, (k,)) * r, -r, r)

  def goal(self, td3_params: td3.TD3Params, ppo_params, obs, mode, key, warm, t,
           noise) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(goal, PPO action to store, its log pi_PPO) from the sub-policy ``mode``; ``noise``
    the std on TD3 goals (the lane's ``middle_goal_noise``).

    Random goals in warm-up (``warmup_goal``; the RANDOM mode's are ``random_goal``). The
    stored PPO action is PPO's own sample ("own", the paper's code) or the executed goal
    ("executed").
    """
    k1, k2, k3 = jax.random.split(key, 3)
    g_random = self.random_goal(k1, self.config.random_goal)
    g_warm = self.random_goal(k1, self.config.warmup_goal)
    g_td3 = self.td3.explore(td3_params, obs, self.context, k2, noise)
    ppo_obs = jp.concatenate([obs, self.target])
    proposal = self.ppo.propose(ppo_params, ppo_obs, k3, t)
    g_ppo = jp.clip(proposal[0], -self.goal_range, self.goal_range)
    g = jp.select([warm, mode == hierarchy.RANDOM, mode == hierarchy.PPO],
                  [g_warm, g_random, g_ppo], g_td3)
    return (g, *self.ppo.stored(ppo_params, ppo_obs, g, proposal, t))

  def new_segment(self, obs, g, ppo_action, log_prob) -> Segment:
    c = self.config.c
    return Segment(obs=jp.zeros((c + 1, self.obs_size)).at[0].set(obs),
                   actions=jp.zeros((c, self.action_size)), rewards=jp.zeros((c,)),
                   success=jp.zeros(()), goal=g, ppo_action=ppo_action, log_prob=log_prob)

  def record(self, seg: Segment, i, a, s_next, reward, success) -> Segment:
    """Step ``i`` of the segment: action a_i, then s_{i+1}, the task reward and success."""
    return seg.replace(obs=seg.obs.at[i + 1].set(s_next), actions=seg.actions.at[i].set(a),
                       rewards=seg.rewards.at[i].set(reward),
                       success=jp.asarray(success, jp.float32))

  @property
  def relabels_at_store(self) -> bool:
    return self.config.middle_relabel == "store"

  def relabelled(self, seg: Segment, low_params: td3.TD3Params, key) -> jax.Array:
    """HIRO's correction of the segment's goal under the Low's target actor (at store)."""
    policy = lambda obs, g: self.low_act(low_params.replace(actor=low_params.target_actor),
                                         obs, g)
    return relabel.relabel(key, policy, seg.obs, seg.actions, seg.goal, self.goal_range,
                           ties=self.config.relabel_ties)[0]

  def pack(self, seg: Segment, g, episode_end, start=None) -> tuple[dict, ppo.Rollout]:
    """The Middle TD3 buffer item (goal ``g``) and the Middle PPO rollout step of a segment.
    ``start``: the Middle TD3's s_0 where it is not the decision state ``seg.obs[0]`` (the
    reset state of an episode's first segment, ``middle_td3_first_state="reset"``); the PPO
    step keeps ``seg.obs[0]``."""
    c, context = self.config.c, self.context
    reward = hierarchy.middle_reward(seg.rewards)
    states = seg.obs if start is None else seg.obs.at[0].set(start)
    tr = td3.Transition(obs=states[0], context=context, action=g, reward=reward,
                        next_obs=seg.obs[c], next_context=context, done=seg.success)
    item = ({"transition": tr} if self.relabels_at_store else
            {"transition": tr, "states": states, "actions": seg.actions})
    done = ppo.terminal(seg.success, episode_end, self.config.returns_cross_episodes)
    step = ppo.Rollout(obs=jp.concatenate([seg.obs[0], self.target]), action=seg.ppo_action,
                       log_prob=seg.log_prob, reward=reward, done=done)
    return item, step

  def close(self, seg: Segment, episode_end, low_params: td3.TD3Params, key,
            start=None) -> tuple[dict, ppo.Rollout]:
    """The segment's buffer item, its goal relabelled at store (``"store"``), and PPO step;
    ``start`` is the Middle TD3's s_0 where it is not ``seg.obs[0]`` (``pack``)."""
    td3_seg = seg if start is None else seg.replace(obs=seg.obs.at[0].set(start))
    g = self.relabelled(td3_seg, low_params, key) if self.relabels_at_store else seg.goal
    return self.pack(seg, g, episode_end, start)

  def _example_segment(self):
    vec = lambda n: jax.ShapeDtypeStruct((n,), jp.float32)
    k = hierarchy.GOAL_SIZE
    return jax.eval_shape(self.new_segment, vec(self.obs_size), vec(k), vec(k),
                          jax.ShapeDtypeStruct((), jp.float32)), vec(k)

  def init_buffer(self) -> buffers.ReplayBuffer:
    segment, goal = self._example_segment()
    item, _ = jax.eval_shape(self.pack, segment, goal, False)
    return buffers.init(item, self.config.middle.buffer_size)

  def init_rollout(self) -> ppo.Rollout:
    """An empty Middle PPO rollout of one env (its steps are ``pack``'s)."""
    segment, goal = self._example_segment()
    return buffers.template(lambda *a: self.pack(*a)[1], segment, goal, False,
                            lead=(self.config.middle_rollout_length,))

  def init_ppo(self, key, num_envs: int) -> MiddlePPOState | NoMiddlePPOState:
    """The Middle PPO's state (nothing for ``NoMiddlePPO``): its learner and a rollout per env."""
    rollout = jax.vmap(lambda _: self.init_rollout())(jp.arange(num_envs))
    return self.ppo.init(key, rollout)

  def policy(self, td3_params: td3.TD3Params, obs) -> jax.Array:
    """The noiseless Middle TD3 goal at s (towards the target)."""
    return self.td3.act(td3_params, obs, self.context)

  def ppo_goal(self, middle_ppo, obs, key) -> jax.Array:
    """The Middle PPO's goal at s as the code evaluates it: a sample (std at step
    ``middle_ppo["t"]``, params ``middle_ppo["params"]``) clipped to the goal range."""
    proposal = self.ppo.propose(middle_ppo["params"], jp.concatenate([obs, self.target]), key,
                                middle_ppo["t"])
    return jp.clip(proposal[0], -self.goal_range, self.goal_range)

  def value(self, td3_params: td3.TD3Params, obs) -> jax.Array:
    """V(s) = min(Q1', Q2')(s, target, pi'_M(s, target)) with the target networks."""
    tgt = jp.broadcast_to(self.context, obs.shape[:-1] + self.context.shape)
    targets = td3_params.replace(actor=td3_params.target_actor)
    q = self.td3.q_values(td3_params.target_critic, obs, tgt, self.td3.act(targets, obs, tgt))
    return q.min(axis=0)

  def td3_update(self, state: td3.TD3State, buffer, low_params: td3.TD3Params, key, t,
                 hp: Numbers) -> tuple[td3.TD3State, dict]:
    """``middle_updates`` TD3 updates (``hp`` the Middle TD3's numbers); with ``"sample"``
    relabelling each batch is relabelled under the current Low actor (``low_params``) first."""
    config, cfg = self.config, self.config.middle

    def one(state, i):
      k1, k2, k3 = jax.random.split(jax.random.fold_in(key, i), 3)
      sample = buffers.sample(buffer, k1, cfg.batch_size)
      batch = sample["transition"]
      if not self.relabels_at_store:
        policy = lambda obs, g: self.low_act(low_params, obs, g)
        relabelled = lambda kk, s, a, g: relabel.relabel(kk, policy, s, a, g, self.goal_range,
                                                         ties=config.relabel_ties)
        goals, _ = jax.vmap(relabelled)(jax.random.split(k2, cfg.batch_size),
                                        sample["states"], sample["actions"], batch.action)
        batch = batch.replace(action=goals)
      n = (t // config.c) * config.middle_updates + i
      return self.td3.update(state, batch, k3, n % cfg.policy_delay == 0, hp)

    return learning.repeat(one, state, config.middle_updates)


def make_middle(obs_size: int, action_size: int, target, config: AgentConfig,
                low_act: Callable) -> Middle:
  """The Middle; ``low_act(low_params, obs, goal)`` is the Low's noiseless actor (HIRO's
  relabelling explains the stored low actions with it)."""
  k = hierarchy.GOAL_SIZE
  goal_range = jp.asarray(config.goal_range, jp.float32)
  target = jp.asarray(target, jp.float32)
  context = target if config.middle_td3_input == "state_target" else jp.zeros((0,), jp.float32)
  learner = td3.make_td3(obs_size, context.shape[0], k, goal_range, config.middle)
  middle_ppo = (MiddlePPO(ppo.make_ppo(obs_size + k, k, config.middle_ppo, goal_range), config)
                if config.uses_middle_ppo else NoMiddlePPO())
  return Middle(config=config, td3=learner, ppo=middle_ppo, obs_size=obs_size,
                action_size=action_size, target=target, goal_range=goal_range, context=context,
                low_act=low_act)
