"""The trainer on the ant: jit smoke tests of ours on AntPush on both physics, and a checkpoint
of the C physics restoring the run bit for bit.

Tiny networks and a 20-step episode; warm-up ends inside the run, so every gate of ours
(Top horizon, Middle PPO, Top PPO, evaluation over ant episodes) compiles and runs once.
"""

import jax
import numpy as np
import pytest

import envs
from nonmono_jax.core import ppo, td3, train
from nonmono_jax.host import checkpoints, methods


def _trainer(physics: str):
  env = envs.make("AntPush", episode_length=20, physics=physics)
  small = td3.TD3Config(hidden=(16, 16), batch_size=4, buffer_size=100)
  net = ppo.PPOConfig(hidden=(16,))
  # On MJX one evaluation kind (S_E) of the preset's three: each kind is a rollout of its own,
  # with an MJX reset and step to compile (8 physics programs in the chunk with three, 4 with
  # one: about half its compile time). The C physics' test keeps all three.
  kinds = {"eval_extra": ()} if physics == "mjx" else {}
  config = methods.build_config("paper", "ours", "AntPush", {
      "warmup_steps": 10, "eval_every": 20, "eval_episodes": 2, "low": small, "middle": small,
      "middle.target_smoothing": False, "middle_ppo": net, "top.horizon": 10,
      "top.train_every": 20, "top.starting_steps": 0, "top.ppo": net, "top.ppo.discrete": True,
      **kinds})[0]
  return train.make_trainer(env, config, num_seeds=2, chunk_steps=20)


def _check_trained(trainer, states, m):
  assert trainer.agent.env.observation_size == 30 and states.goal.shape == (2, 1, 3)
  np.testing.assert_array_equal(states.mode_steps.sum(-1), 30)
  for name in ("low/updated", "middle/updated", "middle_ppo/updated", "top/updated",
               "eval/updated"):
    assert np.all(m[name] > 0), name
  np.testing.assert_array_equal(m["physics/unstable"], 0)
  np.testing.assert_array_equal(m["eval/unstable"], 0)
  for leaf in jax.tree.leaves((states.low.params, states.chooser.learner.params, m)):
    assert np.all(np.isfinite(np.asarray(leaf)))
  assert np.all(np.abs(np.asarray(states.goal)[..., 2]) <= 0.5)  # the ant's z goal range


@pytest.fixture(scope="module")
def c_trainer():
  return _trainer("c")


def test_ours_trains_on_ant_push_with_c_physics(c_trainer):
  states = c_trainer.init(jax.random.PRNGKey(0))
  states, _ = c_trainer.chunk(states, 0)
  states, m = c_trainer.chunk(states, 20)
  _check_trained(c_trainer, states, m)


def test_c_physics_checkpoint_resumes_bit_for_bit(c_trainer, tmp_path):
  """Two chunks straight equal one chunk, a checkpoint, a restore into a fresh state and one
  more chunk: every leaf of the train state, the physics' float64 rows included."""
  straight = c_trainer.init(jax.random.PRNGKey(1))
  straight, _ = c_trainer.chunk(straight, 0)
  straight, m_straight = c_trainer.chunk(straight, 20)
  states, _ = c_trainer.chunk(c_trainer.init(jax.random.PRNGKey(1)), 0)
  ckpts = checkpoints.Checkpoints(str(tmp_path / "ckpt"))
  ckpts.save(20, states)
  like = jax.eval_shape(c_trainer.init, jax.random.PRNGKey(0))
  step, restored = ckpts.restore_newest(like)
  ckpts.close()
  assert step == 20
  resumed, m_resumed = c_trainer.chunk(restored, 20)
  for a, b in zip(jax.tree.leaves((straight, m_straight)), jax.tree.leaves((resumed, m_resumed))):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.slow
def test_ours_trains_on_ant_push_with_mjx_physics():
  trainer = _trainer("mjx")
  states = trainer.init(jax.random.PRNGKey(0))
  states, _ = trainer.chunk(states, 0)
  states, m = trainer.chunk(states, 20)
  _check_trained(trainer, states, m)
