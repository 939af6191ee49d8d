"""The agent step (HIRO's two levels so far): invariants over a short vmapped run."""

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs
from nonmono_jax import agent as agent_lib
from nonmono_jax import td3

C = 5
WARMUP = 60
STEPS = 100


def _config():
  small = td3.TD3Config(hidden=(16, 16), batch_size=8, buffer_size=500)
  return agent_lib.AgentConfig(c=C, goal_range=(4.0, 4.0, 0.0), warmup_steps=WARMUP,
                               low=small, middle=small)


@pytest.fixture(scope="module")
def run():
  env = envs.make("PointMaze", episode_length=50)
  ag = agent_lib.make_agent(env, _config())

  @jax.jit
  def go(keys):
    states = jax.vmap(ag.init)(keys)
    body = lambda st, t: jax.vmap(ag.step, in_axes=(0, None))(st, t)
    mid, m1 = jax.lax.scan(body, states, jp.arange(WARMUP))
    end, m2 = jax.lax.scan(body, mid, WARMUP + jp.arange(STEPS - WARMUP))
    return states, mid, end, jax.tree.map(lambda a, b: jp.concatenate([a, b]), m1, m2)

  keys = jax.random.split(jax.random.PRNGKey(0), 3)
  return ag, env, go, keys, go(keys)


def _same(a, b):
  return all(jax.tree.leaves(jax.tree.map(lambda x, y: bool(jp.all(x == y)), a, b)))


def test_buffers_fill_one_low_transition_per_step_and_one_middle_per_segment(run):
  _, _, _, _, (_, _, end, _) = run
  np.testing.assert_array_equal(end.low_buffer.size, STEPS)
  np.testing.assert_array_equal(end.middle_buffer.size, STEPS // C)


def test_no_updates_during_warmup_then_both_levels_learn(run):
  _, _, _, _, (start, mid, end, metrics) = run
  assert _same(start.low.params, mid.low.params) and _same(start.middle.params, mid.middle.params)
  assert not _same(mid.low.params.critic, end.low.params.critic)
  assert not _same(mid.middle.params.critic, end.middle.params.critic)
  assert not _same(mid.middle.params.actor, end.middle.params.actor)
  low_loss = np.asarray(metrics["low/critic_loss"])
  assert np.all(low_loss[:WARMUP] == 0) and np.all(low_loss[WARMUP:] > 0)
  mid_loss = np.asarray(metrics["middle/critic_loss"])[WARMUP:, 0]
  assert np.count_nonzero(mid_loss) == (STEPS - WARMUP) // C  # once per Middle horizon


def test_middle_transitions_hold_whole_segments(run):
  _, _, _, _, (_, _, end, _) = run
  buf = jax.tree.map(lambda x: np.asarray(x[0]), end.middle_buffer.data)
  tr = buf["transition"]
  n = STEPS // C
  np.testing.assert_allclose(buf["states"][:n, 0], tr.obs[:n])
  np.testing.assert_allclose(buf["states"][:n, -1], tr.next_obs[:n])
  # A segment's last state is the next one's first, except across an episode reset.
  same = np.all(np.isclose(buf["states"][1:n, 0], buf["states"][:n - 1, -1]), axis=-1)
  assert same.sum() == n - 1 - (STEPS // 50 - 1)


def test_episode_clock_and_gates_are_unbatched(run):
  ag, env, _, keys, (_, _, end, _) = run
  np.testing.assert_array_equal(end.env.steps, STEPS % env.episode_length)
  states = jax.vmap(ag.init)(keys)
  jaxpr = str(jax.make_jaxpr(jax.vmap(ag.step, in_axes=(0, None)))(states, jp.array(0)))
  assert jaxpr.count("cond[") >= 4  # segment end, episode reset, low and middle updates


def test_seeds_differ_and_runs_repeat(run):
  _, _, go, keys, (_, _, end, _) = run
  w = jax.tree.leaves(end.low.params.actor)[0]
  assert not np.allclose(w[0], w[1])
  again = go(keys)[2]
  assert _same(end.low.params, again.low.params) and _same(end.env.obs, again.env.obs)


def test_bad_config_fails_before_compiling():
  with pytest.raises(ValueError, match="goal_range"):
    agent_lib.AgentConfig(goal_range=(1.0, 1.0))
  with pytest.raises(ValueError, match="multiple of c"):
    agent_lib.make_agent(envs.make("PointMaze", episode_length=55), agent_lib.AgentConfig())


def test_trainer_chunks_match_the_plain_scan(run):
  """train.make_trainer's chunks are the same program as scanning agent.step by hand."""
  from nonmono_jax import train

  _, env, _, _, (_, _, end, _) = run
  trainer = train.make_trainer(env, _config(), num_seeds=3, chunk_steps=50)
  states = jax.vmap(trainer.agent.init)(jax.random.split(jax.random.PRNGKey(0), 3))
  for t0 in (0, 50):
    states, metrics = trainer.chunk(states, t0)
  assert metrics["success"].shape == (3,)
  np.testing.assert_allclose(states.env.obs, end.env.obs, rtol=1e-5, atol=1e-5)
  with pytest.raises(ValueError, match="num_seeds"):
    train.make_trainer(env, _config(), num_seeds=0, chunk_steps=10)
