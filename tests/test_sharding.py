"""The seed axis sharded across devices gives the same training as one device.

Runs in a subprocess because the CPU device count (``run.use_cpu_devices``, ``--cpu-devices``)
is fixed when jax starts; the session's jax has one CPU device (``conftest.py``).
"""

import os
import subprocess
import sys
import textwrap

from tests_support import CACHE_DIR, ROOT

SCRIPT = textwrap.dedent("""
    import os
    import jax, numpy as np
    jax.config.update("jax_compilation_cache_dir", os.environ["CACHE"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    import envs
    from nonmono_jax.core import td3, train
    from nonmono_jax.host import methods, run
    run.use_cpu_devices(2)  # what --cpu-devices 2 does, before JAX runs anything
    assert jax.device_count() == 2
    run.use_cpu_devices(2)  # again, once JAX runs: the same count is fine
    env = envs.make("PointMaze", episode_length=20)
    small = td3.TD3Config(hidden=(16, 16), batch_size=8, buffer_size=200)
    config = methods.build_config("paper", "hiro", "PointMaze", {
        "c": 5, "warmup_steps": 20, "eval_every": 20, "eval_episodes": 2, "low": small,
        "middle": small})[0]
    out = {}
    for name, devices in (("two", jax.devices()), ("one", jax.devices()[:1])):
      trainer = train.make_trainer(env, config, num_seeds=4, chunk_steps=20, devices=devices)
      states = trainer.init(jax.random.PRNGKey(0))
      for t0 in (0, 20, 40):
        states, metrics = trainer.chunk(states, t0)
      out[name] = (states, metrics)
      print(name, "devices holding the seeds:", len(states.env.obs.sharding.device_set))
      # every leaf stays split by lane, zero-size ones too (PointMaze's blocks: [S, 0, 3]), so
      # the chunk's output is its next input and it compiles once, not once per sharding
      lanes = jax.sharding.PartitionSpec("seeds")
      assert states.env.pipeline_state.blocks.size == 0
      assert all(x.sharding.spec == lanes for x in jax.tree.leaves(states)), [
          (jax.tree_util.keystr(p), x.sharding.spec)
          for p, x in jax.tree_util.tree_leaves_with_path(states) if x.sharding.spec != lanes]
      assert trainer.chunk_program._cache_size() == 1, trainer.chunk_program._cache_size()
    (a, ma), (b, mb) = out["two"], out["one"]
    assert len(a.env.obs.sharding.device_set) == 2 and len(b.env.obs.sharding.device_set) == 1
    assert a.low.params.critic["params"]["dense_0"]["kernel"].shape[0] == 4
    for x, y in zip(jax.tree.leaves((a.low.params, a.env.obs, ma)),
                    jax.tree.leaves((b.low.params, b.env.obs, mb))):
      np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-4, atol=1e-5)
    print("OK")
""")


def test_seed_axis_sharded_on_two_devices_matches_one():
  env = {**os.environ, "CACHE": CACHE_DIR, "PYTHONPATH": ROOT}
  res = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=600)
  assert res.returncode == 0, res.stdout + res.stderr[-4000:]
  assert "OK" in res.stdout
