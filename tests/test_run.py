"""The run library (issue 11): one way to override, config.json as the source of truth, sinks
that get every metric, and an old run folder (made before a preset default changed) that still
resumes, plots and renders."""

import csv
import json
import os

import pytest

from experiments import cli
from nonmono_jax.core import config as config_lib
from nonmono_jax.core import td3
from nonmono_jax.host import folder, methods, plan as plan_lib, provenance, rows as rows_lib
from nonmono_jax.host import run, sinks
from tests_support import ROOT, TINY_OVERRIDES, TINY_RUN, TINY_SIZE


# --- one way to override ------------------------------------------------------------------------

def test_a_dotted_path_changes_that_field_and_keeps_its_neighbours():
  base = methods.build_config("paper", "ours", "AntFall")[0]
  config = config_lib.override(base, {"top.horizon": 100, "middle.target_smoothing": True})
  assert config.top.horizon == 100 and config.middle.target_smoothing
  assert config.top.alpha == base.top.alpha == (-0.2, -0.2, 0.7)  # not wiped by "top.*"
  assert config.middle.hidden == base.middle.hidden
  assert config_lib.differences(base, config) == ["top.horizon", "middle.target_smoothing"]
  # Fields checked together change together; lists become tuples.
  config = config_lib.override(base, {"c": 5, "top.alpha": [0, 0.4, 0.7]})
  assert config.c == 5 and config.top.alpha == (0.0, 0.4, 0.7)
  # A whole value, then the paths under it; a later layer's whole value drops earlier paths.
  small = td3.TD3Config(hidden=(8,), batch_size=4)
  config = config_lib.override(base, {"low": small, "low.batch_size": 2})
  assert config.low.hidden == (8,) and config.low.batch_size == 2
  assert config_lib.merge({"low.hidden": (64,)}, {"low": small}) == {"low": small}
  assert methods.build_config("paper", "hiro", "PointMaze", {"low": small})[0].low == small


@pytest.mark.parametrize("overrides,message", [
    ({"top.nope": 1}, "unknown TopConfig field 'top.nope'"),
    ({"horizon": 3}, "unknown AgentConfig field 'horizon'"),
    ({"low.lr_actor": 2.0}, "low.lr_actor must be in (0, 1]"),
    ({"top.ppo.lr_actor": float("inf")}, "top.ppo.lr_actor must be a finite number"),
    ({"c.x": 1}, "c is not a config with fields"),
])
def test_a_bad_override_names_the_full_dotted_field(overrides, message):
  with pytest.raises(ValueError) as e:
    methods.build_config("paper", "ours", "PointMaze", overrides)[0]
  assert message in str(e.value)


def test_config_json_inverts_for_every_method_task_and_preset():
  for preset in methods.PRESETS:
    for task in methods.TASKS:
      for method in methods.METHODS:
        config, _ = methods.build_config(preset, method, task)
        saved = json.loads(json.dumps(folder.to_jsonable(config)))
        assert config_lib.config_from_dict(saved, config_lib.AgentConfig()) == config
        assert not config_lib.missing_fields(saved, config)


def test_the_command_and_the_library_build_the_same_plan(tmp_path):
  args = cli.make_parser("PointMaze").parse_args(TINY_RUN + ["--method", "ours", "hiro"])
  by_flags = cli.plan_from_args("PointMaze", args)
  by_library = run.new_run("PointMaze", ["ours", "hiro"], preset="quick", run=TINY_SIZE,
                           overrides=TINY_OVERRIDES)
  assert by_flags.configs == by_library.configs and by_flags.spec == by_library.spec
  assert by_library.configs["ours"].low.buffer_size == 800  # sized for the run's 800 steps


# --- sinks --------------------------------------------------------------------------------------

class _Recorder:
  def __init__(self):
    self.calls = []

  def begin(self, method, env_step):
    self.calls.append(("begin", method, env_step))

  def write(self, result):
    self.calls.append(("write", result.method, result.step, sorted(result.metrics)))

  def close(self):
    self.calls.append(("close",))


def test_sinks_are_closed_together_whatever_ends_the_block():
  a, b = _Recorder(), _Recorder()
  with pytest.raises(RuntimeError):
    with sinks.closing([a, b]):
      raise RuntimeError("a NaN, a time limit, Ctrl-C")
  assert a.calls == b.calls == [("close",)]


# --- an old run folder ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def old_run(tmp_path_factory):
  """A tiny run of ours stopped by the time limit after 2 of its 4 chunks, made by the library
  with a recorder sink that sees every chunk (the tests then change a preset default)."""
  out = str(tmp_path_factory.mktemp("old") / "run")
  plan = run.new_run("PointMaze", ["ours"], preset="quick", out=out, run=TINY_SIZE,
                     overrides=TINY_OVERRIDES)
  recorder, results = _Recorder(), []
  clock = run.Clock()
  clock.allows = lambda chunk_s: len(results) < 2
  with run.open_folder(plan):
    outputs = [sinks.MetricsCsv(out), sinks.JsonLines(out), recorder]
    with pytest.raises(run.TimeLimit), sinks.closing(outputs):
      for result in run.run_method(plan, "ours", outputs, clock):
        results.append(result)
  return out, recorder, results


def test_metrics_csv_shows_the_low_and_each_evaluation_the_run_makes(old_run):
  """The Low's columns in every row; S_E per evaluation kind where the run evaluates it (the
  point preset: only the held goals, which is its S_E)."""
  rows = rows_lib.MetricsFile(os.path.join(old_run[0], "metrics.csv")).read()
  assert rows and all(r[c] != "" for r in rows for c in rows_lib.LOW_COLUMNS)
  assert all(-100 < float(r["low_reward"]) < 0 and 0 <= float(r["low_subgoal_reached"]) <= 1
             for r in rows)
  assert all(abs(float(r["low_subgoal_progress"])) < 20 for r in rows)
  evaluated = [r for r in rows if r["eval_success"] != ""]
  assert evaluated and all(r["eval_success_held"] == r["eval_success"] for r in evaluated)
  assert all(r["eval_success_requery"] == r["eval_success_ppo"] == "" for r in rows)


def test_every_metric_reaches_the_json_lines_file(old_run):
  out, recorder, results = old_run
  assert [c[0] for c in recorder.calls] == ["begin", "write", "write", "close"]
  assert [r.step for r in results] == [200, 400]
  with open(os.path.join(out, "metrics.jsonl")) as f:
    records = [json.loads(line) for line in f]
  assert len(records) == 2 * 2  # seeds x chunks
  names = set(results[0].metrics)
  assert {"low/critic_loss", "count/TD3", "reward"} <= names
  for record in records:
    assert names <= set(record) and set(rows_lib.COLUMNS) <= set(record)
  assert [r["seed"] for r in records] == [0, 1, 0, 1]
  assert records[2]["count/TD3"] == results[1].metrics["count/TD3"][0]


@pytest.fixture
def preset_changed(monkeypatch):
  """Today's preset of ours has another S_O during the starting mode (0.8) than the one the
  run was made with (0.9)."""
  monkeypatch.setitem(methods.METHOD_OVERRIDES, "ours", {**methods.METHOD_OVERRIDES["ours"],
                                                        "top.s_o_start": 0.8})


def _event_tags(folder) -> set:
  """The scalar tags of the TensorBoard event files in ``folder`` (TFRecord framing: length,
  its CRC, the Event, its CRC)."""
  import struct

  from tensorboardX.proto import event_pb2

  tags = set()
  for name in os.listdir(folder):
    with open(os.path.join(folder, name), "rb") as f:
      data = f.read()
    pos = 0
    while pos < len(data):
      (length,) = struct.unpack("<Q", data[pos:pos + 8])
      event = event_pb2.Event.FromString(data[pos + 12:pos + 12 + length])
      tags |= {v.tag for v in event.summary.value}
      pos += 12 + length + 4
  return tags


def test_every_metric_reaches_tensorboard(old_run, tmp_path):
  _, _, results = old_run
  board = sinks.TensorBoard(str(tmp_path))
  with sinks.closing([board]):
    board.begin("ours", 0)
    board.write(results[-1])
  tags = _event_tags(tmp_path / "tensorboard" / "ours")
  assert set(results[-1].metrics) <= tags
  assert {"eval_success", "low_critic_loss", "eval_success/seed1"} <= tags


def test_an_old_run_folder_resumes_plots_and_renders_with_a_warning(old_run, preset_changed,
                                                                    tmp_path, capsys):
  from experiments import plot, render

  out = os.path.join(tmp_path, "run")
  import shutil
  shutil.copytree(old_run[0], out)
  # The folder as an older version wrote it: overrides nested, a field the code added since.
  path = os.path.join(out, "config.json")
  payload = folder.read_json(path)
  payload["overrides"] = {"top": {"starting_steps": 100}, **{
      k: v for k, v in payload["overrides"].items() if k != "top.starting_steps"}}
  del payload["configs"]["ours"]["eval_target_networks"]
  # ... and a metrics.csv without the columns the code added since (Middle decisions, counts
  # after the starting mode): its rows keep its columns
  old_columns = [c for c in rows_lib.COLUMNS if not c.startswith(("decisions_", "cum_decisions_",
                                                             "cum_steps_after_start_"))]
  metrics = os.path.join(out, "metrics.csv")
  old_rows = rows_lib.MetricsFile(metrics).read()
  with open(metrics, "w", newline="") as f:
    w = csv.DictWriter(f, old_columns, lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    w.writerows(old_rows)
  assert payload["host"] == provenance.host()  # the machine type its rows reproduce on
  payload["host"]["cpu"] = "another CPU"
  folder.write_json(path, payload)
  plan = run.load_run(out)
  assert any("started on another machine type (cpu 'another CPU'" in w for w in plan.warnings)
  assert plan.configs["ours"].top.s_o_start == 0.9  # config.json's, not today's 0.8
  assert any("top.s_o_start 0.9 (today 0.8)" in w for w in plan.warnings)
  assert any("has no eval_target_networks" in w for w in plan.warnings)
  capsys.readouterr()
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  got = capsys.readouterr()
  assert "ours: resumed from step 400" in got.out
  sessions = folder.read_sessions(out)  # the run's start, then this resume, each with its host
  assert [s["resumed"] for s in sessions] == [False, True]
  assert sessions[1]["host"] == provenance.host() and "commit" in sessions[1]["code"]
  assert "warning:" in got.err and "top.s_o_start 0.9 (today 0.8)" in got.err
  rows = rows_lib.MetricsFile(os.path.join(out, "metrics.csv")).read()
  assert [int(r["env_step"]) for r in rows] == [200, 200, 400, 400, 600, 600, 800, 800]
  assert list(rows[-1]) == old_columns  # the resumed rows in the file's own columns
  with open(os.path.join(out, "metrics.jsonl")) as f:
    assert [json.loads(line)["env_step"] for line in f] == [200, 200, 400, 400, 600, 600,
                                                             800, 800]
  assert plot.main([out, "--out", str(tmp_path / "fig")]) == 0
  roll = render.rollout(out, "ours", 1)
  assert roll["step"] == 800 and roll["pos"].shape == (101, 3) and roll["warnings"]


# A run folder as the code of 2026-12-02 wrote it (the command is in its config.json: ours and
# HIRO, TINY_RUN), its last checkpoints (800) removed: stopped at 600 of 800 steps.
FOLDER_2026_12_02 = os.path.join(ROOT, "tests", "data", "run_2026-12-02")


@pytest.mark.slow
def test_a_run_folder_of_2026_12_02_loads_resumes_plots_and_renders(tmp_path, capsys):
  """Every later version must read this committed folder: it loads, resumes to its end (the
  rows it had up to its checkpoint kept as they were), plots and renders."""
  import shutil
  from experiments import plot, render

  out = str(tmp_path / "run")
  shutil.copytree(FOLDER_2026_12_02, out)
  committed = {(r["method"], r["seed"], r["env_step"]): r
               for r in rows_lib.MetricsFile(os.path.join(out, "metrics.csv")).read()}
  assert run.load_run(out).configs["ours"].top.starting_steps == 100
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert "resumed from step 600" in capsys.readouterr().out
  assert [s["resumed"] for s in folder.read_sessions(out)] == [True]  # none recorded before
  rows = rows_lib.MetricsFile(os.path.join(out, "metrics.csv")).read()
  keys = {(r["method"], r["seed"], r["env_step"]): r for r in rows}
  assert len(rows) == len(keys) == len(committed) == 2 * 2 * 4  # methods x seeds x chunks
  assert set(keys) == set(committed)
  for key, row in keys.items():
    if int(key[2]) <= 600:
      assert row == committed[key], key
  assert plot.main([out, "--out", str(tmp_path / "fig")]) == 0
  assert render.rollout(out, "hiro", 0)["step"] == 800


def test_a_json_lines_file_drops_what_follows_the_checkpoint_on_resume(tmp_path):
  path = tmp_path / "metrics.jsonl"
  lines = [{"method": "ours", "env_step": 200}, {"method": "hiro", "env_step": 600},
           {"method": "ours", "env_step": 400}]
  path.write_text("".join(json.dumps(r) + "\n" for r in lines) + '{"method": "ours", "env')
  sinks.JsonLines(str(tmp_path)).begin("ours", 200)
  assert [json.loads(l) for l in path.read_text().splitlines()] == lines[:2]


def test_a_config_json_that_today_cannot_rebuild_still_loads(old_run, tmp_path):
  out = str(tmp_path / "run")
  os.makedirs(out)
  payload = folder.read_json(os.path.join(old_run[0], "config.json"))
  payload["overrides"]["a_field_since_removed"] = 1
  folder.write_json(os.path.join(out, "config.json"), payload)
  plan = plan_lib.load_run(out)
  assert plan.configs["ours"] == run.load_run(old_run[0]).configs["ours"]
  assert any("cannot be rebuilt from today's presets" in w for w in plan.warnings)


# --- the ant's physics --------------------------------------------------------------------------

def test_the_ant_physics_is_recorded_and_an_old_ant_run_keeps_mjx(tmp_path):
  plan = plan_lib.new_run("AntPush", ["hiro"], preset="quick", out=str(tmp_path / "a"))
  assert plan.physics == "c"  # auto on a CPU
  from nonmono_jax.host import programs as programs_lib
  assert plan.env().physics == "c"
  assert programs_lib.Programs(plan).trainer("hiro").agent.env.physics == "c"
  payload = folder.to_json(plan)
  assert payload["physics"] == "c"
  assert plan_lib.from_json(payload, plan.out).physics == "c"
  mjx = plan_lib.new_run("AntPush", ["hiro"], preset="quick", physics="mjx")
  assert plan_lib.from_json(folder.to_json(mjx), plan.out).physics == "mjx"
  del payload["physics"]  # a run folder from before the choice ran on MJX
  assert plan_lib.from_json(payload, plan.out).physics == "mjx"
  payload["physics"] = "warp"
  with pytest.raises(ValueError, match="physics must be c or mjx, got 'warp'"):
    plan_lib.from_json(payload, plan.out)
  with pytest.raises(ValueError, match="PointMaze has no physics choice"):
    plan_lib.new_run("PointMaze", ["hiro"], physics="c")
  assert plan_lib.new_run("PointMaze", ["hiro"]).physics is None
  with pytest.raises(ValueError, match="--physics must be one of auto, c, mjx"):
    plan_lib.new_run("AntFall", ["hiro"], physics="C")


def test_the_ant_contacts_are_recorded_and_an_old_ant_run_keeps_mujoco3(tmp_path):
  """``--contacts`` (envs.contacts) reaches the run's env and config.json, a new run's default
  the paper's MuJoCo 2.0 as near as it goes; a run folder from before the choice ran on
  MuJoCo 3's contacts and resumes on them."""
  plan = plan_lib.new_run("AntFall", ["hiro"], preset="quick", out=str(tmp_path / "a"))
  assert plan.contacts == "mujoco200" and plan.env().config.contacts == "mujoco200"
  two = plan_lib.new_run("AntFall", ["hiro"], preset="quick", contacts="mujoco2")
  assert two.env().mj_model.geom_margin.max() == 0.005
  payload = folder.to_json(two)
  assert payload["contacts"] == "mujoco2"
  assert plan_lib.from_json(payload, plan.out).contacts == "mujoco2"
  del payload["contacts"]  # a run folder from before the choice
  assert plan_lib.from_json(payload, plan.out).contacts == "mujoco3"
  payload["contacts"] = "mujoco1"
  with pytest.raises(ValueError, match="contacts must be one of .*, got 'mujoco1'"):
    plan_lib.from_json(payload, plan.out)
  with pytest.raises(ValueError, match="--contacts: PointMaze has no contact settings"):
    plan_lib.new_run("PointMaze", ["hiro"], contacts="mujoco2")
  assert plan_lib.new_run("PointMaze", ["hiro"]).contacts is None
  with pytest.raises(ValueError, match="--contacts must be one of mujoco3, mujoco2"):
    plan_lib.new_run("AntFall", ["hiro"], contacts="2.0")
  args = cli.make_parser("AntFall").parse_args(["--method", "hiro", "--contacts", "mujoco2"])
  assert cli.plan_from_args("AntFall", args).contacts == "mujoco2"
  assert "--contacts" not in cli.make_parser("PointFall").format_help()


def test_the_task_registry_names_each_task_once():
  """methods.TASKS is the one list of tasks: each has its env, its presets, its experiment
  module (which reads its task from the registry) and its calibration floor."""
  import importlib

  import envs
  assert set(methods.TASKS) == set(envs.NAMES)
  for task, preset in methods.TASKS.items():
    assert preset.env == task and preset.robot == ("ant" if envs.has_physics(task) else "point")
    module = importlib.import_module(f"experiments.{task.lower()}")
    assert methods.task_of_module(module.__name__) == task
    for name in methods.PRESETS:
      methods.build_config(name, "ours", task)
  assert methods.TASKS["PointPush"].random_success == 0.004
  with pytest.raises(ValueError, match="no task named 'antswim'"):
    methods.task_of_module("experiments.antswim")


def test_fields_added_since_a_run_keep_the_behaviour_it_ran_with():
  """The first Ant Push study's config.json predates the code's evaluation, the Middle TD3's
  first state and the warm-up goals, which today's Ant presets take: loaded, its configs keep
  the earlier behaviour (the fields' defaults), so it resumes and reproduces as it ran."""
  plan = plan_lib.load_run(os.path.join(ROOT, "results", "antpush", "ours"))
  config = plan.configs["ours"]
  assert (config.eval_goal, config.eval_extra, config.middle_td3_first_state,
          config.warmup_goal) == ("held", (), "last", "uniform")
  assert config.episode_start == "last"  # what it saved stays
  today = methods.build_config("paper", "ours", "AntPush")[0]
  assert (today.eval_goal, today.middle_td3_first_state) == ("requery", "reset")
  assert any("has no " in w and "middle_td3_first_state" in w
             and "the behaviour before they were added" in w for w in plan.warnings)
  # the parity fixtures' options too (docs/fidelity.md, "(fixtures)")
  assert (config.low.target_noise, config.top.ppo.value_weighting, config.relabel_ties) == (
      "sample", "sample", "original")
  assert (today.low.target_noise, today.top.ppo.value_weighting, today.relabel_ties) == (
      "batch", "batch", "random")


def test_a_checkpoint_without_the_later_state_fields_is_filled_as_its_code_ran():
  """``SeedState.filled``: the Middle TD3's s_0 of the current segment is the segment's first
  state (what the code before ``segment_start`` stored), the per-kind S_E zero."""
  import jax
  import jax.numpy as jp
  import numpy as np
  import envs
  from nonmono_jax.core import agent as agent_lib

  config = methods.build_config("paper", "ours", "PointMaze", {**TINY_OVERRIDES})[0]
  agent = agent_lib.make_agent(envs.make("PointMaze", episode_length=100), config)
  state = jax.vmap(agent.init)(jax.random.split(jax.random.PRNGKey(0), 2))
  n = len(jax.tree.leaves(state))
  junk = state.replace(segment_start=jp.full_like(state.segment_start, 7.0),
                       eval_by_kind=jp.ones_like(state.eval_by_kind))
  old = junk.filled(n - 2)  # a checkpoint of the fields before segment_start
  np.testing.assert_array_equal(old.segment_start, state.segment.obs[..., 0, :])
  np.testing.assert_array_equal(old.eval_by_kind, 0.0)
  assert junk.filled(n).segment_start.max() == 7.0  # nothing missing: nothing changes
