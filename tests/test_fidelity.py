"""Fidelity to the paper's public PyTorch code where its text is silent (docs/fidelity.md).

Each test pins one behaviour of the paper's code that this project once did differently:
the paper presets, TD3's policy delay, the Middle TD3's done and relabelling, the Middle PPO's
stored sample, and evaluation with the target networks.
"""

import dataclasses

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs
from nonmono_jax.core import buffers, evaluate, hierarchy, low as low_lib
from nonmono_jax.core import middle as middle_lib
from nonmono_jax.core import lanes, relabel, td3
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.host import methods

OBS, ACT = 7, 2
SMALL = td3.TD3Config(hidden=(8,), batch_size=4, buffer_size=64)


@pytest.mark.parametrize("task,steps", [("AntPush", 3_150_000), ("AntFall", 6_000_000)])
def test_paper_presets(task, steps):
  """Buffers hold the whole run (nothing is evicted), actors update on every critic update,
  the Middle PPO's std is 0.6 goal units, Ref:PPO's stays 0.6 and trains every 40 steps."""
  for method in methods.METHODS:
    config, spec = methods.build_config("paper", method, task)
    assert spec.steps == steps
    assert config.low.buffer_size >= steps and config.middle.buffer_size >= steps // config.c
    assert config.low.policy_delay == config.middle.policy_delay == 1
    assert config.middle_relabel == "store" and config.eval_target_networks
    assert config.middle_ppo.mean_head == "linear" and config.middle_ppo_sample == "own"
    assert config.middle_ppo.std_init == 0.6
    if method == "ref-ppo":
      assert config.middle_ppo.std_decay == 0.0 and config.middle_ppo_every == 40
    else:
      assert config.middle_ppo.std_decay == 0.05 and config.middle_ppo_every == 30
  # a widened run (E envs per seed) holds the same env steps
  config, spec = methods.build_config("paper", "ours", task, widen={"envs_per_seed": 16})
  assert config.low.buffer_size >= spec.steps * 16 >= steps


def test_policy_delay_one_updates_the_actor_on_every_update():
  low = low_lib.make_low(OBS, ACT, 1.0, AgentConfig(low=dataclasses.replace(SMALL,
                                                                         policy_delay=1)))
  state = low.td3.init(jax.random.PRNGKey(0))
  buffer = low.init_buffer()
  tr = jax.vmap(low.transition)(jp.ones((8, OBS)), jp.ones((8, 3)), jp.ones((8, ACT)),
                                jp.zeros((8, OBS)))
  buffer = buffers.add(buffer, tr)
  update = jax.jit(low.update)
  for t in range(3):
    new, m = update(state, buffer, jax.random.PRNGKey(t), t, lanes.of(SMALL))
    assert m["actor_loss"] != 0
    assert not np.allclose(jax.tree.leaves(new.params.actor)[0],
                           jax.tree.leaves(state.params.actor)[0])
    state = new


def _middle(**fields):
  config = methods.build_config("paper", "ours", "PointPush", {
      "low": SMALL, "middle": SMALL, "middle.target_smoothing": False,
      "middle_ppo.hidden": (8,), **fields})[0]
  low = low_lib.make_low(OBS, ACT, 1.0, config)
  return config, low, middle_lib.make_middle(OBS, ACT, jp.array([0.0, 9.5, 0.5]), config,
                                             low.td3.act)


def _segment(mid, c, success):
  key = jax.random.PRNGKey(3)
  seg = mid.new_segment(jp.zeros(OBS), jp.array([1.0, -2.0, 0.0]), jp.zeros(3), jp.zeros(()))
  for i in range(c):
    key, k1, k2 = jax.random.split(key, 3)
    seg = mid.record(seg, i, jax.random.uniform(k1, (ACT,), minval=-1, maxval=1),
                     jax.random.normal(k2, (OBS,)), -1.0, success if i == c - 1 else 0.0)
  return seg


@pytest.mark.parametrize("success", [0.0, 1.0])
def test_middle_transition_done_is_success_and_relabelled_at_store(success):
  """The paper's code stores done = success at s_c and the goal relabelled once, under the
  Low's *target* actor; "sample" keeps the segment for HIRO's per-batch relabelling."""
  config, low, mid = _middle()
  low_params = low.td3.init(jax.random.PRNGKey(1)).params
  low_params = low_params.replace(target_actor=low.td3.init(jax.random.PRNGKey(2)).params.actor)
  seg = _segment(mid, config.c, success)
  key = jax.random.PRNGKey(4)
  item, step = mid.close(seg, False, low_params, key)
  assert float(item["transition"].done) == success and float(step.done) == success
  assert set(item) == {"transition"}
  target_policy = lambda s, g: low.td3.act(low_params.replace(actor=low_params.target_actor), s, g)
  online_policy = lambda s, g: low.td3.act(low_params, s, g)
  goal_range = jp.asarray(config.goal_range)
  want = relabel.relabel(key, target_policy, seg.obs, seg.actions, seg.goal, goal_range)[0]
  np.testing.assert_allclose(item["transition"].action, want)
  online = relabel.relabel(key, online_policy, seg.obs, seg.actions, seg.goal, goal_range)[0]
  assert not np.allclose(online, want)  # the target actor made the difference
  _, _, per_batch = _middle(middle_relabel="sample")
  item, _ = per_batch.close(seg, False, low_params, key)
  np.testing.assert_allclose(item["transition"].action, seg.goal)
  assert item["states"].shape == (config.c + 1, OBS)


@pytest.mark.parametrize("sample", ["own", "executed"])
def test_middle_ppo_stores_its_own_sample_in_other_modes(sample):
  config, _, mid = _middle(middle_ppo_sample=sample)
  td3_params = mid.td3.init(jax.random.PRNGKey(0)).params
  ppo_params = mid.ppo.learner.init(jax.random.PRNGKey(1)).params
  obs, key, t = jp.ones(OBS), jax.random.PRNGKey(2), 0
  for mode in (hierarchy.TD3, hierarchy.RANDOM, hierarchy.PPO):
    g, stored, logp = mid.goal(td3_params, ppo_params, obs, mode, key, False, t,
                              config.middle_goal_noise)
    x = jp.concatenate([obs, jp.array([0.0, 9.5, 0.5])])
    sampled, sampled_logp = mid.ppo.learner.act(ppo_params, x, jax.random.split(key, 3)[2],
                                        mid.ppo.std(t))
    if sample == "own":  # PPO's own sample, whichever mode ran the segment
      np.testing.assert_allclose(stored, sampled)
      np.testing.assert_allclose(logp, sampled_logp, rtol=1e-6)
      if mode != hierarchy.PPO:
        assert not np.allclose(stored, g)
    else:
      np.testing.assert_allclose(stored, g)
      want = mid.ppo.learner.log_prob(ppo_params, x, g, mid.ppo.std(t))
      np.testing.assert_allclose(logp, want, rtol=1e-6)


def test_evaluation_uses_the_target_actors():
  env = envs.make("PointMaze", episode_length=20)
  learner = td3.make_td3(env.observation_size, 3, 2, 1.0, SMALL)
  mid = td3.make_td3(env.observation_size, 3, 3, jp.array([4.0, 4.0, 0.0]), SMALL)
  lp, mp = (learner.init(jax.random.PRNGKey(0)).params, mid.init(jax.random.PRNGKey(1)).params)
  lp = lp.replace(target_actor=learner.init(jax.random.PRNGKey(2)).params.actor)
  mp = mp.replace(target_actor=mid.init(jax.random.PRNGKey(3)).params.actor)
  key = jax.random.PRNGKey(4)
  mid_act = lambda params, obs: mid.act(params, obs, env.target)
  on_targets = evaluate.make_evaluate(env, 10, learner.act, mid_act, 2)(lp, mp, None, key)
  online = evaluate.make_evaluate(env, 10, learner.act, mid_act, 2, target_networks=False)
  swapped = online(lp.replace(actor=lp.target_actor), mp.replace(actor=mp.target_actor), None,
                   key)
  jax.tree.map(np.testing.assert_allclose, on_targets, swapped)
  assert not np.allclose(on_targets.distance, online(lp, mp, None, key).distance)


def test_table_counts_modes_in_middle_decisions():
  """--table shows the paper's unit: Middle decisions after the starting mode (env steps in
  brackets); a run from before those columns shows its env steps."""
  from experiments import plot

  def row(seed, **extra):
    base = {"task": "PointMaze", "method": "ours", "seed": str(seed), "env_step": "1000",
            "eval_success": "1.0", "eval_return": "-5", "cum_steps_TD3": "700",
            "cum_steps_PPO": "200", "cum_steps_RANDOM": "100"}
    return {**base, **extra}

  new = {f"cum_decisions_after_start_{m}": v for m, v in zip(plot.MODES, ("60", "15", "5"))}
  new.update({f"cum_steps_after_start_{m}": v for m, v in zip(plot.MODES, ("600", "150", "50"))})
  table = plot.markdown_table(plot.summary([row(0, **new), row(1, **new)]))
  assert "| 60 [60, 60] (600) | 15 [15, 15] (150) | 5 [5, 5] (50) |" in table
  assert "TD3 decisions after the starting mode" in table
  old = plot.markdown_table(plot.summary([row(0), row(1)]))
  assert ("| 700 [700, 700] env steps | 200 [200, 200] env steps | 100 [100, 100] env steps |"
          in old)


def test_run_buffers_hold_the_whole_run_unless_a_size_is_given():
  """--steps resizes both replay buffers to the run (nothing evicted); an explicit
  --low.buffer_size wins and makes a ring."""
  from experiments import cli
  parser = cli.make_parser("PointMaze")
  plan = cli.plan_from_args("PointMaze", parser.parse_args(
      ["--preset", "quick", "--method", "ours", "--steps", "1200", "--chunk", "400"]))
  config = plan.configs["ours"]
  assert (config.low.buffer_size, config.middle.buffer_size) == (1200, 120)
  plan = cli.plan_from_args("PointMaze", parser.parse_args(
      ["--preset", "quick", "--method", "ours", "--steps", "1200", "--chunk", "400",
       "--low.buffer_size", "500"]))
  assert (plan.configs["ours"].low.buffer_size, plan.configs["ours"].middle.buffer_size) == (
      500, 120)
