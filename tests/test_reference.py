"""The reference harness (reference/, docs/reference.md): the mujoco_py and wandb stand-ins,
the logs' cut on resume, the patches, the run folder's config check; with the reference venv
and the fetched code (absent in CI: those tests skip), a tiny run of the paper's code that is
the same twice and the same stopped and resumed, and the batched evaluation against the
code's."""

import importlib.util
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import mujoco
import numpy as np
import pytest

import reference
from reference import harness, logs, patches, physics
from reference import run as run_lib
from tests.tests_support import ROOT

# A small model with a free body, two hinges with motors and a floor: contacts, limits and an
# RK4 integrator, as the ant has.
XML = """
<mujoco><option timestep="0.02" integrator="RK4"/>
  <default><joint limited="true" armature="1" damping="1"/>
    <geom condim="3" margin="0.01" friction="1 0.5 0.5" density="5"/></default>
  <worldbody><geom name="floor" type="plane" size="10 10 1" conaffinity="1"/>
    <body name="torso" pos="0 0 0.75"><freejoint name="root"/>
      <geom name="torso_geom" type="sphere" size="0.25" conaffinity="0"/>
      <body name="leg" pos="0.2 0 0"><joint name="hip" type="hinge" axis="0 0 1" range="-30 30"/>
        <geom name="leg_geom" type="capsule" size="0.08" fromto="0 0 0 0.4 0 0"
              conaffinity="0"/>
        <body pos="0.4 0 0"><joint name="ankle" type="hinge" axis="0 1 0" range="30 70"/>
          <geom name="foot" type="capsule" size="0.08" fromto="0 0 0 0.4 0 -0.4"
                conaffinity="0"/></body></body></body></worldbody>
  <actuator><motor joint="hip" ctrlrange="-30 30" ctrllimited="true" gear="1"/>
    <motor joint="ankle" ctrlrange="-30 30" ctrllimited="true" gear="1"/></actuator>
</mujoco>"""


def _load_standin(name):
  """Import a stand-in by path under its own name, without touching sys.path."""
  path = reference.STANDINS / name / "__init__.py"
  spec = importlib.util.spec_from_file_location(f"standin_{name}", path)
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  return module


@pytest.fixture
def mujoco_py():
  return _load_standin("mujoco_py")


@pytest.fixture
def model_path(tmp_path):
  path = tmp_path / "m.xml"
  path.write_text(XML)
  return str(path)


def _gym_like_step(sim, ctrl, frame_skip=5):
  """gym 0.15.7's MujocoEnv.do_simulation."""
  sim.data.ctrl[:] = ctrl
  for _ in range(frame_skip):
    sim.step()


def test_the_standin_steps_as_raw_mj_step(mujoco_py, model_path):
  """The same initial state and controls give the same trajectory, bit for bit."""
  sim = mujoco_py.MjSim(mujoco_py.load_model_from_path(model_path))
  model = mujoco.MjModel.from_xml_path(model_path)
  data = mujoco.MjData(model)
  rng = np.random.default_rng(0)
  qpos = sim.data.qpos.copy() + rng.uniform(-0.1, 0.1, model.nq)
  qvel = rng.normal(0, 0.1, model.nv)
  sim.set_state(mujoco_py.MjSimState(0.0, qpos, qvel, None, {}))
  sim.forward()
  data.qpos[:], data.qvel[:] = qpos, qvel
  mujoco.mj_forward(model, data)
  for _ in range(60):
    ctrl = rng.uniform(-30, 30, model.nu).astype(np.float32)
    _gym_like_step(sim, ctrl)
    data.ctrl[:] = ctrl
    for _ in range(5):
      mujoco.mj_step(model, data)
    np.testing.assert_array_equal(sim.data.qpos, data.qpos)
    np.testing.assert_array_equal(sim.data.qvel, data.qvel)
  assert sim.data.time == pytest.approx(60 * 5 * 0.02)
  np.testing.assert_array_equal(sim.data.get_body_xpos("torso"), data.body("torso").xpos)


def test_the_standin_state_reset_and_model(mujoco_py, model_path):
  model = mujoco_py.load_model_from_path(model_path)
  sim = mujoco_py.MjSim(model)
  assert model.opt.timestep == 0.02 and model.nq == 9 and model.nv == 8 and model.na == 0
  np.testing.assert_array_equal(model.actuator_ctrlrange, [[-30, 30], [-30, 30]])
  assert model.body_name2id("torso") == 1 and mujoco_py.get_version() >= "1.50"
  _gym_like_step(sim, [10.0, -10.0])
  state = sim.get_state()
  assert state.act is None and state.udd_state == {} and state.time > 0
  _gym_like_step(sim, [-5.0, 5.0])
  sim.set_state(state)  # time, qpos, qvel only (mujoco_py's set_state)
  np.testing.assert_array_equal(sim.data.qpos, state.qpos)
  assert sim.data.time == state.time
  np.testing.assert_array_equal(sim.data.ctrl, [-5.0, 5.0])
  sim.reset()
  assert sim.data.time == 0 and not sim.data.ctrl.any()
  np.testing.assert_array_equal(sim.data.qpos, model.qpos0)
  with pytest.raises(NotImplementedError):
    mujoco_py.MjViewer(sim)


def test_the_standin_raises_on_mujoco_warnings_like_mujoco_py(mujoco_py, model_path, tmp_path,
                                                              monkeypatch):
  monkeypatch.chdir(tmp_path)  # MuJoCo writes its warnings to ./MUJOCO_LOG.TXT
  sim = mujoco_py.MjSim(mujoco_py.load_model_from_path(model_path))
  sim.data.qvel[0] = 1e11  # past mjMAXVAL: MuJoCo warns (BADQVEL) and resets the data
  with pytest.raises(mujoco_py.MujocoException, match="mjWARN_BADQVEL"):
    sim.step()
  sim.data.qvel[0] = 1e11
  with mujoco_py.ignore_mujoco_warnings():
    sim.step()
  assert mujoco_py.warning_counts["mjWARN_BADQVEL"] == 2


def test_the_model_hook_changes_each_loaded_model(mujoco_py, model_path):
  def margins(model):
    model.geom_margin[:] = 0.0
    model.opt.timestep = 0.01
  physics.register("test-no-margins", margins)
  try:
    mujoco_py.set_model_hook(physics.hook("test-no-margins"))
    model = mujoco_py.load_model_from_path(model_path)
    assert model.opt.timestep == 0.01 and not model.geom_margin.any()
    mujoco_py.set_model_hook(physics.hook("as-is"))
    assert mujoco_py.load_model_from_path(model_path).geom_margin.max() == 0.01
  finally:
    del physics.SETTINGS["test-no-margins"]
  with pytest.raises(ValueError, match="unknown physics"):
    physics.hook("nope")


def test_the_wandb_standin_records_every_call_as_plain_numbers():
  wandb = _load_standin("wandb")
  seen = []
  wandb.sinks.append(lambda record, step: seen.append((record, step)))
  wandb.init(project="x")
  wandb.log({"success rate": np.float64(0.5)}, step=10)
  wandb.log({"critic_loss low": np.array(2.5, np.float32), "n": 3}, step=np.int64(11))
  assert seen == [({"success rate": 0.5}, 10), ({"critic_loss low": 2.5, "n": 3}, 11)]
  assert wandb.calls == seen and wandb.init_args == ((), {"project": "x"})


def test_logs_are_cut_back_to_a_checkpoint(tmp_path):
  first = logs.Logs(str(tmp_path), 0)
  for t in (500, 1000, 1500):
    first.evaluation({"t": t, "step": t - 300, "success_rate": 0.0})
    first.window({"t": t, "step": t - 300})
    first.wandb(t, t - 300, {"success rate": 0.0})
  first.close()
  again = logs.Logs(str(tmp_path), 1000)  # resumed at the top of iteration 1000
  again.close()
  assert [r["t"] for r in logs.read_csv(again.eval_path)] == ["500"]
  assert [r["t"] for r in logs.read_csv(again.window_path)] == ["500", "1000"]
  lines = [json.loads(x) for x in open(again.jsonl_path)]
  assert [x["_t"] for x in lines] == [500]


def test_an_older_harness_windows_file_gains_the_new_columns(tmp_path):
  """A run begun by the harness before the subgoal columns: its rows keep their values, the
  new columns empty, and the resumed rows line up under the widened header."""
  old = logs.WINDOW_COLUMNS[:13]
  path = tmp_path / "windows.csv"
  path.write_text(",".join(old) + "\n" + ",".join(["500", "200"] + ["1"] * 11) + "\n")
  again = logs.Logs(str(tmp_path), 1000)
  again.window({"t": 1000, "step": 700, "segments": 25, "subgoal_distance": 7.5})
  again.close()
  rows = logs.read_csv(path)  # (timing columns left out)
  assert path.read_text().splitlines()[0] == ",".join(logs.WINDOW_COLUMNS)
  assert rows[0]["low_intrinsic_reward_mean"] == "1" and rows[0]["subgoal_distance"] == ""
  assert rows[1]["segments"] == "25" and rows[1]["subgoal_distance"] == "7.5"
  path.write_text("t,something_else\n1,2\n")
  with pytest.raises(ValueError, match="its columns are not this harness's"):
    logs.Logs(str(tmp_path), 0)


def test_patches_replace_one_exact_line(tmp_path):
  (tmp_path / "a.py").write_text("x = 1\n    y = np.argmax(z)\n")
  patch = patches.Patch("a.py", "y = np.argmax(z)", "y = 2", "a test")
  done = patches.apply(tmp_path, (patch,))
  assert (tmp_path / "a.py").read_text() == "x = 1\n    y = 2\n"
  assert done == [{"path": "a.py", "line": 2, "old": "y = np.argmax(z)", "new": "y = 2",
                   "why": "a test"}]
  with pytest.raises(RuntimeError, match="found 0"):
    patches.apply(tmp_path, (patch,))


def test_a_run_folder_keeps_its_settings(tmp_path):
  args = run_lib.parse(["--out", str(tmp_path / "r"), "--seed", "3"])
  config = run_lib.config_from(args, "cmd")
  run_lib.check_folder(config)
  saved = json.loads((tmp_path / "r" / "config.json").read_text())
  assert saved["seed"] == 3 and saved["threads"] == 1 and saved["seeded"]
  assert saved["start_timestep"] == 100_000 and saved["evaluation_interval"] == 10_000
  run_lib.check_folder(run_lib.config_from(
      run_lib.parse(["--out", str(tmp_path / "r"), "--seed", "3", "--stop-at", "9"]), "cmd"))
  with pytest.raises(SystemExit, match="seed=3"):
    run_lib.check_folder(run_lib.config_from(
        run_lib.parse(["--out", str(tmp_path / "r"), "--seed", "4"]), "cmd"))


def test_a_moved_run_folder_resumes_where_it_is(tmp_path):
  """A folder's config.json names the absolute folder it was started in; a copy elsewhere (another
  disk, another machine) is the same run, and now says where it is."""
  run_lib.check_folder(run_lib.config_from(
      run_lib.parse(["--out", str(tmp_path / "a"), "--seed", "3"]), "cmd"))
  shutil.copytree(tmp_path / "a", tmp_path / "b")
  run_lib.check_folder(run_lib.config_from(
      run_lib.parse(["--out", str(tmp_path / "b"), "--seed", "3"]), "cmd"))
  assert json.loads((tmp_path / "b" / "config.json").read_text())["out"] == str(tmp_path / "b")
  with pytest.raises(SystemExit, match="seed=3"):
    run_lib.check_folder(run_lib.config_from(
        run_lib.parse(["--out", str(tmp_path / "b"), "--seed", "4"]), "cmd"))


def test_evaluation_helpers():
  limited = harness._limited_range(2)
  assert (list(limited(10)), list(limited(5)), list(limited(8))) == ([0], [0, 1], list(range(8)))

  class Buffer:
    def __init__(self, capacity, dim):
      self.capacity = capacity
  assert harness._one_row_more(Buffer)(100, 3).capacity == 101


def test_the_codes_model_files_are_closed_and_removed(tmp_path):
  """``_XmlFiles``, the code's maze env's ``tempfile``: a descriptor closed at once, the file
  there until the env is made, then removed; the rest of ``tempfile`` as it is."""
  files = harness._XmlFiles()
  fd, path = files.mkstemp(text=True, suffix=".xml", dir=tmp_path)
  with pytest.raises(OSError):
    os.fstat(fd)
  pathlib.Path(path).write_text("<mujoco/>")
  files.remove()
  assert not os.path.exists(path) and files.paths == []
  assert files.gettempdir() == tempfile.gettempdir()


def test_cross_eval_summaries():
  """Code - ours over seeds (every resample of 3 seeds: the interval runs from the lowest
  seed's difference to the highest), and ours - code over the pooled episodes of the draws."""
  from reference import cross_eval
  rows = [{"seed": k, "draw": d, "code_distance": 10.0 + k + d, "eval_distance": 10.0}
          for k in range(3) for d in range(2)]
  diff = cross_eval.summary({"t": 1}, rows)["difference"]
  assert (diff["seeds"], diff["mean"], diff["ci95"]) == (3, 1.5, [0.5, 2.5])
  meta = {"t": 1, "results": [{"draw": d, "code_success": 0.0, "code_distances": [9.0, 11.0]}
                              for d in range(2)]}
  out = cross_eval.mirror_summary(meta, [(0.0, [8.0, 8.0]), (0.02, [8.0, 10.0])])
  assert [r["our_distance"] for r in out["results"]] == [8.0, 9.0] and out["t"] == 1
  assert out["difference"]["episodes"] == [4, 4] and out["difference"]["mean"] == -1.5
  lower, upper = out["difference"]["ci95"]
  assert -3.5 <= lower < -1.5 < upper <= 0.5


# ----- with the reference venv and the fetched code ---------------------------------------------

VENV = pathlib.Path(os.environ.get("REFERENCE_VENV") or reference.default_venv())
HAVE_REFERENCE = (VENV / "bin" / "python").exists() and (reference.code_dir() / "hiro.py").exists()
needs_reference = pytest.mark.skipif(
    not HAVE_REFERENCE, reason="no reference venv or fetched code (python -m reference.setup)")
TINY = ["--steps", "1500", "--start-timestep", "300", "--evaluation-interval", "500",
        "--eval-episodes", "2", "--episode-len", "200", "--checkpoint-every", "500",
        "--window", "250"]


def _run(out, *extra, **environ):
  return subprocess.run([sys.executable, "-m", "reference.run", "--out", str(out), *TINY,
                         *extra], cwd=ROOT, capture_output=True, text=True, timeout=900,
                        env=dict(os.environ, PYTHONPATH=str(ROOT), **environ))


def _same_weights(a, b):
  code = ("import sys, torch; a, b = (torch.load(p, weights_only=False)['weights'] "
          "for p in sys.argv[1:]); assert a.keys() == b.keys(); "
          "assert all(torch.equal(a[k][n], b[k][n]) if torch.is_tensor(a[k][n]) else True "
          "for k in a for n in a[k] if n != 'state' and n != 'param_groups'); "
          "assert all(torch.equal(x['exp_avg'], y['exp_avg']) for k in a if 'state' in a[k] "
          "for x, y in zip(a[k]['state'].values(), b[k]['state'].values()))")
  return subprocess.run([str(VENV / "bin" / "python"), "-c", code, str(a), str(b)],
                        capture_output=True, text=True)


@pytest.mark.slow
@needs_reference
def test_a_run_is_the_same_twice_and_stopped_and_resumed(tmp_path):
  """Same seed, same rows; stopped at 1,000, moved to another folder and resumed there, the
  same rows and final weights as the run straight through (timing columns aside)."""
  straight, stopped = tmp_path / "straight", tmp_path / "stopped"
  assert _run(straight).returncode == 0
  stop = _run(stopped, "--stop-at", "1000")
  assert stop.returncode == 3, stop.stdout + stop.stderr
  assert not (stopped / "final.pt").exists()
  idle = _run(stopped, "--stop-at", "1000")  # the same command again: nothing to do
  assert idle.returncode == 3 and "stopped already" in idle.stdout
  resumed = shutil.move(stopped, tmp_path / "moved")
  again = _run(resumed)
  assert again.returncode == 0 and "resuming" in again.stdout, again.stdout + again.stderr
  for name in ("evaluations.csv", "windows.csv"):
    rows = logs.read_csv(straight / name)
    assert rows == logs.read_csv(resumed / name) and rows
  assert (straight / "wandb.jsonl").read_bytes() == (resumed / "wandb.jsonl").read_bytes()
  check = _same_weights(straight / "final.pt", resumed / "final.pt")
  assert check.returncode == 0, check.stderr
  assert _run(resumed).stdout.strip().endswith("finished already")
  sessions = json.loads((resumed / "provenance.json").read_text())["sessions"]
  assert [s["resume_t"] for s in sessions] == [None, 1000]  # the calls that trained
  assert all(s["harness"]["commit"] and s["host"] and "cpu" in s for s in sessions)


@pytest.mark.slow
@needs_reference
def test_the_batched_evaluation_judges_every_episode_as_the_code():
  r = subprocess.run([sys.executable, "-m", "reference.compare_eval", "--episodes", "5",
                      "--episode-len", "150", "--perturb", "1"], cwd=ROOT, capture_output=True,
                     text=True, timeout=900, env=dict(os.environ, PYTHONPATH=str(ROOT)))
  assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
  summary = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
  assert len(summary) == 6
  assert all(s["judgements_differing"] == 0 and s["max_final_distance_gap"] == 0.0
             for s in summary)


def test_the_physics_settings_are_the_projects_contacts():
  """``--physics mujoco2`` / ``mujoco200`` apply ``envs.contacts.apply_contacts``, loaded from
  its file (the reference venv has no jax); ``as-is`` and ``mujoco3`` leave the model."""
  import mujoco
  from envs import ant, contacts, maze
  from reference import physics
  xml = ant.ant_maze_xml(maze.MAZES["Push"].layout(8.0), optimised=False)
  assert {"as-is", "mujoco2", "mujoco200", "mujoco3"} <= set(physics.names())
  assert physics.hook("as-is") is None and physics.hook("mujoco3") is None
  for name in ("mujoco2", "mujoco200"):
    theirs, ours = (mujoco.MjModel.from_xml_string(xml) for _ in range(2))
    physics.hook(name)(theirs)
    contacts.apply_contacts(ours, name)
    for field in ("geom_margin", "body_mass", "body_invweight0"):
      np.testing.assert_array_equal(getattr(theirs, field), getattr(ours, field))
    assert theirs.geom_margin.max() == 0.005 and theirs.opt.tolerance == ours.opt.tolerance
  with pytest.raises(ValueError, match="unknown physics 'mujoco1'; known: as-is"):
    physics.hook("mujoco1")


@pytest.mark.slow
@needs_reference
def test_a_run_with_the_studys_settings_leaves_out_the_ppo_evaluation(tmp_path):
  """``--eval batched-td3 --physics mujoco200``, the decisive study's: S_E every evaluation,
  the Middle PPO's left empty, the settings recorded."""
  out = tmp_path / "run"
  r = _run(out, "--eval", "batched-td3", "--physics", "mujoco200", "--steps", "1001")
  assert r.returncode == 0, r.stdout + r.stderr
  rows = logs.read_csv(out / "evaluations.csv")
  assert rows and all(row["higher_success_rate"] == "" and row["successes_ppo"] == ""
                      and 0 <= float(row["success_rate"]) <= 1 for row in rows)
  config = json.loads((out / "config.json").read_text())
  assert (config["eval"], config["physics"]) == ("batched-td3", "mujoco200")
  windows = logs.read_csv(out / "windows.csv")
  assert all(int(w["segments"]) == 25 and 0 <= float(w["subgoal_reached"]) <= 1
             and float(w["subgoal_start"]) - float(w["subgoal_distance"])
             == pytest.approx(float(w["subgoal_progress"]), abs=1e-9) for w in windows)


@needs_reference
def test_a_run_leaves_no_model_files_behind(tmp_path):
  """The code's maze env writes its model to a new temp file for each env it makes (the
  training env and every evaluation's) and keeps it; the harness removes each once loaded."""
  tmp = tmp_path / "tmp"
  tmp.mkdir()
  r = _run(tmp_path / "run", "--steps", "1001", TMPDIR=str(tmp))
  assert r.returncode == 0, r.stdout + r.stderr
  assert sorted(p.name for p in tmp.rglob("*.xml")) == []


@needs_reference
def test_the_codes_training_rate_is_read_per_cpu_second_after_its_warmup(tmp_path):
  """``benchmarks.paper_code``'s side of the code: the windows after the warm-up, each timed
  by the wall clock and by the process's CPU time (evaluation and checkpoints left out)."""
  from benchmarks import paper_code
  got = paper_code.run_code(str(tmp_path / "code"), steps=200, warmup=100, window=100,
                            threads=1)
  assert got["windows"] == 2 and got["threads"] == 1
  assert got["env_steps_per_s"] > 0 and got["env_steps_per_cpu_s"] > 0
  windows = logs.read_csv(tmp_path / "code" / "windows.csv", drop=())
  assert [w["step"] for w in windows] == ["0", "100", "200"]
  assert all(float(w["train_steps_per_cpu_s"]) > 0 for w in windows)


def _actors_npz(path, **broken):
  """Fresh Ant-shaped actors of ours (the Low: (s, g) -> 8 torques in +-30; the Middle: s ->
  a goal in +-(10, 10, 0.5)) as ``reference.cross_eval.export`` writes them."""
  import jax
  from nonmono_jax.core import td3
  from nonmono_jax.core.config import TD3Config
  from reference import cross_eval
  config = TD3Config(hidden=(300, 300), init="torch")
  low_td3 = td3.make_td3(30, 3, 8, 30.0, config)
  middle_td3 = td3.make_td3(30, 0, 3, (10.0, 10.0, 0.5), config)
  low = low_td3.init(jax.random.PRNGKey(0)).params
  middle = middle_td3.init(jax.random.PRNGKey(1)).params
  rng = np.random.default_rng(0)
  obs = rng.normal(size=(64, 30)).astype(np.float32)
  goal = rng.normal(size=(64, 3)).astype(np.float32)
  data = {"probe_obs": obs, "probe_goal": goal, "low_scale": np.full(8, 30.0, np.float32),
          "middle_scale": np.asarray([10, 10, 0.5], np.float32),
          "middle_context": np.zeros(0, np.float32),
          "seed0/probe_low": np.asarray(jax.vmap(low_td3.act, (None, 0, 0))(low, obs, goal)),
          "seed0/probe_middle": np.asarray(jax.vmap(
              lambda o: middle_td3.act(middle, o, np.zeros(0, np.float32)))(obs))}
  for name, params in (("low", low), ("middle", middle)):
    for i, w in enumerate(cross_eval.torch_layout(params.actor)):
      data[f"seed0/{name}/{i}"] = w
  data.update(broken)
  meta = {"seeds": [0], "contacts": "mujoco200",
          "ours": {"0": {"eval_success": 0.0, "eval_distance": 18.0}}}
  np.savez(path, meta=np.asarray(json.dumps(meta)), **data)
  return data


def _cross_eval(path):
  return subprocess.run([str(VENV / "bin" / "python"), "-m", "reference.cross_eval", "--weights",
                         str(path), "--episodes", "2", "--episode-len", "30"], cwd=ROOT,
                        capture_output=True, text=True, timeout=900,
                        env=dict(os.environ, PYTHONPATH=str(ROOT)))


@needs_reference
def test_the_codes_evaluation_runs_our_actors(tmp_path):
  """``reference.cross_eval`` in the reference venv: our actors' weights go into the code's
  ActorLow and ActorHigh, act as ours on the probes and are run by the code's evaluation; the
  layers' rows out of order, or a scale not the code's, are refused before evaluating."""
  path = tmp_path / "actors.npz"
  data = _actors_npz(path)
  r = _cross_eval(path)
  assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
  [result] = json.loads(path.with_suffix(".json").read_text())
  assert result["code_success"] == 0.0 and len(result["code_distances"]) == 2
  assert all(17 < d < 21 for d in result["code_distances"])  # 30 steps from the start
  assert (result["eval_distance"], "ours S_E 0.00 distance 18.00") == (18.0, r.stdout.split(
      "; ")[-1].strip())
  rows = data["seed0/low/0"][::-1].copy()  # the first layer's units out of order, not its biases
  _actors_npz(path, **{"seed0/low/0": rows})
  r = _cross_eval(path)
  assert r.returncode != 0
  assert "the code's low actor with the other side's weights acts otherwise" in r.stderr
  _actors_npz(path, low_scale=np.full(8, 20.0, np.float32))
  r = _cross_eval(path)
  assert r.returncode != 0 and "the Low's action scale is [20.0" in r.stderr


@pytest.mark.slow
@needs_reference
def test_our_evaluation_runs_the_codes_actors(tmp_path):
  """``reference.cross_eval`` on a run folder of the code's: its final target actors act in
  our evaluation as in the code's (the probe check) and both evaluate them; ``render`` draws
  them in our env."""
  run = tmp_path / "run"
  assert _run(run).returncode == 0
  out = tmp_path / "cross.json"
  r = subprocess.run([sys.executable, "-m", "reference.cross_eval", str(run), "--episodes", "2",
                      "--episode-len", "50", "--json", str(out)], cwd=ROOT, capture_output=True,
                     text=True, timeout=900, env=dict(os.environ, PYTHONPATH=str(ROOT)))
  assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
  got = json.loads(out.read_text())
  assert (got["t"], got["checkpoint"], got["contacts"], got["seeds"]) == (
      1500, "final.pt", "mujoco3", [0])
  [row] = got["results"]
  for side in ("our", "code"):
    assert row[f"{side}_success"] == 0.0 and len(row[f"{side}_distances"]) == 2
    assert all(13 < d < 21 for d in row[f"{side}_distances"])  # 50 steps from the start
  assert got["difference"]["episodes"] == [2, 2]
  from experiments import render
  assert render.main([str(run), "--max-frames", "5"]) == 0
  assert (run / "the-code_seed0.gif").stat().st_size > 1000
  with pytest.raises(SystemExit):
    render.main([str(run), "--seed", "best"])
