"""Variants as lanes: ours and an ablation in one program give each variant's own run."""

import itertools
import os

import jax
import numpy as np
import pytest

from nonmono_jax.core import lanes, train
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import check_group
from nonmono_jax.host import folder, methods, run, sinks
from nonmono_jax.host import plan as plan_lib
from tests.tests_support import TINY_OVERRIDES

# Past warm-up (100) and the starting mode (100) the Top trains at steps 399 and 799.
STEPS, CHUNK, SEEDS, EPISODE = 800, 400, 2, 100


def tiny(method, overrides=None):
  return methods.build_config("paper", method, "PointMaze", {**TINY_OVERRIDES, **(overrides or {})},
                              run={"steps": STEPS})[0]


def _run(trainer):
  states = trainer.init(jax.random.PRNGKey(3))
  chunks = []
  for t0 in range(0, STEPS, CHUNK):
    states, metrics = trainer.chunk(states, t0)
    chunks.append(jax.device_get(metrics))
  return jax.device_get(states), chunks


# The ablation with learners' numbers of its own too: they are lanes' numbers as well.
ABLATION = {"low.lr_critic": 3e-3, "middle.tau": 0.01, "top.ppo.clip": 0.3}


@pytest.fixture(scope="module")
def runs():
  env = plan_lib.make_env("PointMaze", EPISODE)
  ablation = tiny("ours-no-mods", ABLATION)
  group = train.make_group_trainer(env, [tiny("ours"), ablation], SEEDS, CHUNK)
  alone = train.make_trainer(env, ablation, SEEDS, CHUNK)
  return group, _run(group), _run(alone)


def test_a_lane_of_a_group_is_that_variant_run_alone_bit_for_bit(runs):
  """One program path: a config alone is a group of one, its numbers arguments as in a
  group, so its lane computes the same bits."""
  group, (g_states, g_chunks), (a_states, a_chunks) = runs
  assert group.num_lanes == 2 * SEEDS and g_chunks[0]["success"].shape == (2 * SEEDS,)
  assert a_chunks[-1]["top/updated"].min() > 0  # the Top trained in the compared chunk
  for g, a in zip(g_chunks, a_chunks):
    assert set(g) == set(a)
    for name in a:
      np.testing.assert_array_equal(group.lanes(g, 1)[name], a[name], err_msg=name)
  jax.tree.map(np.testing.assert_array_equal, group.lanes(g_states, 1), a_states)


def test_a_trainer_built_again_shares_its_programs_and_keeps_its_numbers(runs):
  """A trainer built again for one env and static key (a notebook's cell run again, the next
  run of a session) reuses the traced programs (``train._programs``); its lanes' numbers stay
  its own: the ablation, sharing ours' program after ours ran, computes the bits it computes
  alone."""
  _, _, (a_states, a_chunks) = runs
  env = plan_lib.make_env("PointMaze", EPISODE)
  assert plan_lib.make_env("PointMaze", EPISODE) is env
  ours = train.make_trainer(env, tiny("ours"), SEEDS, CHUNK)
  ablation = train.make_trainer(env, tiny("ours-no-mods", ABLATION), SEEDS, CHUNK)
  assert ablation.chunk_program is ours.chunk_program and ablation.init is ours.init
  other = train.make_trainer(env, tiny("ours"), 2 * SEEDS, CHUNK)
  assert other.chunk_program is not ours.chunk_program
  _run(ours)
  states, chunks = _run(ablation)
  for c, a in zip(chunks, a_chunks):
    for name in a:
      np.testing.assert_array_equal(c[name], a[name], err_msg=name)
  jax.tree.map(np.testing.assert_array_equal, states, a_states)


def test_gates_stay_branches_with_batched_numbers():
  """Each lane's numbers are batched, the step counter is not: the gates stay ``cond``s."""
  env = plan_lib.make_env("PointMaze", EPISODE)
  group = train.make_group_trainer(env, [tiny("ours"), tiny("ours-no-mods")], SEEDS, CHUNK)
  states = jax.eval_shape(group.init, jax.random.PRNGKey(0))
  hp = jax.tree.map(np.asarray, lanes.stack([tiny("ours")] * group.num_lanes))
  jaxpr = str(jax.make_jaxpr(jax.vmap(group.agent.step, in_axes=(0, None, 0)))(
      states, np.int32(0), hp))
  assert jaxpr.count("cond[") >= 10, jaxpr.count("cond[")


def test_the_variants_differ_in_what_their_numbers_change(runs):
  group, (_, g_chunks), _ = runs
  ours, no_mods = group.lanes(g_chunks[-1], 0), group.lanes(g_chunks[-1], 1)
  assert not np.allclose(ours["horizon/r_final"], no_mods["horizon/r_final"])
  assert not np.allclose(ours["low/critic_loss"], no_mods["low/critic_loss"])


def test_only_configs_with_one_static_key_share_a_program():
  assert lanes.static_key(tiny("ours", {"top.alpha": (0.1, 0.2, 0.3)})) == lanes.static_key(
      tiny("ours-no-loss-mod"))
  with pytest.raises(ValueError, match="switch"):
    check_group([tiny("ours"), tiny("hiro")])
  with pytest.raises(ValueError, match="top.horizon"):
    check_group([tiny("ours"), tiny("ours", {"top.horizon": 20})])


def _plan(out, sweep=None):
  return run.new_run("PointMaze", ["ours", "ours-no-mods"], preset="quick", out=str(out),
                     overrides=TINY_OVERRIDES, sweep=sweep,
                     run={"seeds": SEEDS, "steps": STEPS, "chunk": CHUNK,
                          "checkpoint_every": CHUNK, "episode_length": EPISODE})


def _train(plan, resume=False, chunks=None):
  with run.open_folder(plan, resume=resume):
    outputs = [sinks.MetricsCsv(plan.out)]
    with sinks.closing(outputs):
      (group,) = plan.groups()
      return list(itertools.islice(run.run_group(plan, group, outputs, log=lambda _: None),
                                   chunks))


def test_a_group_run_writes_each_variant_and_resumes_exactly(tmp_path):
  """ours and ours-no-mods as one program: their own rows and checkpoints; stopped after a
  chunk and resumed, the same metrics.csv as a run that never stopped."""
  whole = _plan(tmp_path / "whole")
  assert whole.groups() == [["ours", "ours-no-mods"]]
  results = _train(whole)
  assert [r.method for r in results] == ["ours", "ours-no-mods"] * 2
  assert sorted(os.listdir(tmp_path / "whole" / "checkpoints")) == ["ours", "ours-no-mods"]
  _train(_plan(tmp_path / "stopped"), chunks=2)  # the first chunk of both, checkpointed
  _train(run.load_run(str(tmp_path / "stopped")), resume=True)
  assert ((tmp_path / "whole" / "metrics.csv").read_bytes()
          == (tmp_path / "stopped" / "metrics.csv").read_bytes())


def test_a_sweep_names_its_variants_and_saves_their_values(tmp_path):
  plan = _plan(tmp_path, sweep={"top.s_o": [(0.6, 0.6, 0.6), (0.4, 0.5, 0.6)]})
  names = ["ours+top.s_o=0.6,0.6,0.6", "ours+top.s_o=0.4,0.5,0.6",
           "ours-no-mods+top.s_o=0.6,0.6,0.6", "ours-no-mods+top.s_o=0.4,0.5,0.6"]
  assert plan.groups() == [names]
  assert plan.configs[names[1]].top.s_o == (0.4, 0.5, 0.6)
  with run.open_folder(plan):
    pass
  loaded = run.load_run(str(tmp_path))
  assert loaded.configs == plan.configs and not loaded.warnings
  assert loaded.variants[names[3]] == {"method": "ours-no-mods",
                                       "overrides": {"top.s_o": [0.4, 0.5, 0.6]}}


def test_a_sweep_runs_a_method_once_where_it_does_not_read_the_swept_field(tmp_path):
  """HIRO has no Top and ours-no-mods no alpha: a sweep of top.alpha would run their seeds
  as identical lanes, once per value."""
  alphas = [(0, 0.4, 0.7), (0, 0.2, 0.35)]
  plan = run.new_run("PointMaze", ["ours", "ours-no-mods", "hiro"], preset="quick",
                     out=str(tmp_path), sweep={"top.alpha": alphas, "top.s_o": [(0.6,) * 3]})
  assert list(plan.configs) == ["ours+top.alpha=0,0.4,0.7+top.s_o=0.6,0.6,0.6",
                                "ours+top.alpha=0,0.2,0.35+top.s_o=0.6,0.6,0.6",
                                "ours-no-mods+top.s_o=0.6,0.6,0.6", "hiro"]
  assert plan.configs["ours-no-mods+top.s_o=0.6,0.6,0.6"].top.alpha == (0.0, 0.4, 0.7)  # preset
  assert plan.configs["hiro"] == run.new_run("PointMaze", ["hiro"], preset="quick",
                                             out=str(tmp_path)).configs["hiro"]
  with pytest.raises(ValueError, match="--sweep top.alpha: not read by hiro"):
    run.new_run("PointMaze", ["hiro"], preset="quick", out=str(tmp_path),
                sweep={"top.alpha": alphas})
  assert AgentConfig(switch="homeostasis", explore_mode="random").reads("homeostasis.rho")
  assert not AgentConfig(switch="homeostasis", explore_mode="random").reads("middle_ppo.clip")
  assert AgentConfig(switch="homeostasis", explore_mode="ppo").reads("middle_ppo.clip")


def test_a_run_from_before_variants_resumes_its_methods_one_after_another(tmp_path):
  """Its methods may stand at different steps: they keep running alone, as they ran."""
  with run.open_folder(_plan(tmp_path)):
    pass
  payload = folder.read_config(str(tmp_path))
  del payload["grouped"], payload["variants"]
  assert plan_lib.from_json(payload, str(tmp_path)).groups() == [["ours"], ["ours-no-mods"]]


def test_traced_numbers_are_declared_once_on_their_fields():
  """``numbers.traced`` on a field is the whole declaration: the paths, the lane's numbers and
  the static key all follow from it."""
  paths = set(lanes.paths(AgentConfig()))
  assert {"top.alpha", "top.reward_mod", "top.loss_mod", "homeostasis.rho", "low.gamma",
          "middle.tau", "top.ppo.clip", "middle_ppo.lr_actor", "middle_goal_noise"} <= paths
  assert not any(p.split(".")[-1] in ("hidden", "batch_size", "horizon", "k_epochs", "c")
                 for p in paths)
  hp = lanes.of(tiny("ours-no-reward-mod", {"top.alpha": (0.0, 0.5, 0.25)}))
  assert float(hp.top.reward_mod) == 0.0 and float(hp.top.loss_mod) == 1.0
  np.testing.assert_array_equal(hp.top.alpha, np.float32([0.0, 0.5, 0.25]))
  assert hp.low.gamma.dtype == np.float32 and len(jax.tree.leaves(hp)) == len(paths)
  with pytest.raises(AttributeError, match="no traced number 'c'"):
    hp.c
