"""The benchmarks' plumbing: what they time is the trainer's own chunk, and they run. (Their
numbers are measured by running them, never here.)"""

import jax
import numpy as np

import envs
from benchmarks import common, train_throughput
from nonmono_jax.core import train
from nonmono_jax.host import methods


def test_a_compiled_chunk_is_the_trainers_chunk():
  config = methods.build_config("paper", "ours", "PointMaze", {
      "warmup_steps": 20, "top.starting_steps": 20, "low.hidden": (16, 16),
      "middle.hidden": (16, 16), "low.batch_size": 8, "middle.batch_size": 8})[0]
  trainer = train.make_trainer(envs.make("PointMaze", episode_length=50), config, num_seeds=2,
                               chunk_steps=60)
  key = jax.random.PRNGKey(3)
  compiled = common.compile_chunk(trainer, trainer.init(key))
  ours, m_ours = compiled(trainer.init(key), 0)
  theirs, m_theirs = trainer.chunk(trainer.init(key), 0)
  for a, b in zip(jax.tree.leaves((ours, m_ours)), jax.tree.leaves((theirs, m_theirs))):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
  assert train.compiled_bytes(compiled)["total"] > 0
  assert "fusion" in compiled.as_text()


def test_train_throughput_times_a_chunk():
  r = train_throughput.measure("PointPush", "hiro", seeds=1, num_envs=1, chunk=10, repeats=1,
                               time_eval=False)
  assert r["env_steps_per_s"] > 0 and r["seeds"] == 1
