"""The trainer on the MJX ant: a jit smoke test of ours on AntPush (learning is a GPU job).

Tiny networks and a 20-step episode; warm-up ends inside the run, so every gate of ours
(Top horizon, Middle PPO, Top PPO, evaluation over MJX episodes) compiles and runs once.
"""

import jax
import numpy as np
import pytest

import envs
from nonmono_jax import methods, ppo, td3, train


@pytest.mark.slow
def test_ours_trains_on_ant_push():
  env = envs.make("AntPush", episode_length=20)
  small = td3.TD3Config(hidden=(16, 16), batch_size=4, buffer_size=100)
  net = ppo.PPOConfig(hidden=(16,))
  config = methods.make_config("ours", "AntPush", {
      "warmup_steps": 10, "eval_every": 20, "eval_episodes": 1, "low": small, "middle": small,
      "middle.target_smoothing": False, "middle_ppo": net, "top.horizon": 10,
      "top.train_every": 20, "top.starting_steps": 0, "top.ppo": net, "top.ppo.discrete": True})
  trainer = train.make_trainer(env, config, num_seeds=2, chunk_steps=20)
  states = trainer.init(jax.random.PRNGKey(0))
  states, m = trainer.chunk(states, 0)
  states, m = trainer.chunk(states, 20)
  assert env.observation_size == 30 and states.goal.shape == (2, 1, 3)
  np.testing.assert_array_equal(states.mode_steps.sum(-1), 30)
  for name in ("low/updated", "middle/updated", "middle_ppo/updated", "top/updated",
               "eval/updated"):
    assert np.all(m[name] > 0), name
  for leaf in jax.tree.leaves((states.low.params, states.chooser.learner.params, m)):
    assert np.all(np.isfinite(np.asarray(leaf)))
  assert np.all(np.abs(np.asarray(states.goal)[..., 2]) <= 0.5)  # the ant's z goal range
