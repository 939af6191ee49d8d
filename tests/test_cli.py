"""The experiment command: good and bad input, run folders, resume equivalence, kill and resume."""

import argparse
import collections
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from experiments import cli
from tests_support import CACHE_DIR, ROOT, TINY_RUN
TINY = TINY_RUN


def _rows(out):
  with open(os.path.join(out, "metrics.csv"), newline="") as f:
    return list(csv.DictReader(f))


def _bytes(out):
  with open(os.path.join(out, "metrics.csv"), "rb") as f:
    return f.read()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
  """An uninterrupted tiny run of ours and Ref:PPO."""
  out = str(tmp_path_factory.mktemp("ref") / "run")
  assert cli.main("PointMaze", TINY + ["--method", "ours", "ref-ppo", "--out", out]) == 0
  return out


def test_tensorboard_files_on_request(tmp_path):
  out = tmp_path / "run"
  assert cli.main("PointMaze", TINY + ["--method", "hiro", "--out", str(out), "--steps", "400",
                                       "--tensorboard"]) == 0
  events = os.listdir(out / "tensorboard" / "hiro")
  assert len(events) == 1 and events[0].startswith("events.out.tfevents")
  assert os.path.getsize(out / "tensorboard" / "hiro" / events[0]) > 1000


def test_run_folder_holds_config_metrics_and_checkpoints(reference):
  config = json.load(open(os.path.join(reference, "config.json")))
  assert config["methods"] == ["ours", "ref-ppo"] and config["task"] == "PointMaze"
  assert config["configs"]["ours"]["low"]["hidden"] == [16, 16]
  assert config["configs"]["ours"]["top"]["starting_steps"] == 100
  assert config["versions"]["jax"] and config["platform"] == "cpu"
  head = subprocess.run(["git", "-C", ROOT, "rev-parse", "HEAD"], capture_output=True, text=True)
  if head.returncode == 0:  # a checkout: the commit where the run reproduces bit for bit
    assert config["code"]["commit"] == head.stdout.strip()
  rows = _rows(reference)
  assert len(rows) == 2 * 2 * 4  # methods x seeds x chunks
  assert [r["env_step"] for r in rows[:4]] == ["200", "200", "400", "400"]
  last = [r for r in rows if r["method"] == "ours"][-2:]
  for r in last:  # 700 steps after warm-up, in modes
    assert sum(int(r[f"cum_steps_{m}"]) for m in ("TD3", "PPO", "RANDOM")) == 700 * 1
    assert r["low_critic_loss"] != "" and r["top_loss"] != ""
  assert all(r["top_loss"] == "" for r in rows if r["method"] == "ref-ppo")
  for method in ("ours", "ref-ppo"):
    assert sorted(os.listdir(os.path.join(reference, "checkpoints", method)))[-1] == "800"


def test_resume_after_a_stop_gives_the_same_metrics(reference, tmp_path):
  out = str(tmp_path / "run")
  # Stop ours after 2 of its 4 chunks: keep only what a run killed then would have left.
  # Its replay buffers are those of the 800-step run (the presets size them for the run).
  assert cli.main("PointMaze", TINY + ["--method", "ours", "ref-ppo", "--out", out,
                                       "--steps", "400", "--low.buffer_size", "800",
                                       "--middle.buffer_size", "80"]) == 0
  # A run stopped at step 400 is a run configured for 800 that has reached 400.
  cfg = json.load(open(os.path.join(out, "config.json")))
  cfg["run"]["steps"] = 800
  json.dump(cfg, open(os.path.join(out, "config.json"), "w"))
  for d in ("ref-ppo",):  # ref-ppo had not started yet when ours was stopped
    import shutil
    shutil.rmtree(os.path.join(out, "checkpoints", d))
  with open(os.path.join(out, "metrics.csv")) as f:
    lines = [l for l in f if ",ref-ppo," not in l]
  with open(os.path.join(out, "metrics.csv"), "w") as f:
    f.writelines(lines)
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _rows(out) == _rows(reference)
  assert _bytes(out) == _bytes(reference)  # one line ending, whatever the resume history


def _started_past_a_checkpoint(out: str, stderr) -> subprocess.Popen:
  """The tiny run of ours and Ref:PPO into ``out`` in a process of its own, once ours has
  written a checkpoint (it must still be running then)."""
  env = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}
  proc = subprocess.Popen([sys.executable, "-m", "experiments.pointmaze", *TINY,
                           "--method", "ours", "ref-ppo", "--out", out], cwd=ROOT, env=env,
                          stdout=subprocess.DEVNULL, stderr=stderr, text=True)
  ckpts = os.path.join(out, "checkpoints", "ours")
  deadline = time.time() + 300
  while time.time() < deadline and proc.poll() is None:
    if os.path.isdir(ckpts) and any(d.isdigit() for d in os.listdir(ckpts)):
      break
    time.sleep(0.05)
  assert proc.poll() is None, "the run ended before it could be stopped"
  return proc


@pytest.mark.slow  # starts processes
def test_sigkill_leaves_a_resumable_run(reference, tmp_path):
  out = str(tmp_path / "run")
  proc = _started_past_a_checkpoint(out, subprocess.DEVNULL)
  os.kill(proc.pid, signal.SIGKILL)
  proc.wait()
  rows = _rows(out)  # readable, consistent up to a checkpoint
  assert rows and {r["method"] for r in rows} <= {"ours", "ref-ppo"}
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _rows(out) == _rows(reference)
  assert _bytes(out) == _bytes(reference)  # one line ending, whatever the resume history


@pytest.mark.slow  # starts processes
def test_sigterm_is_one_line_and_leaves_a_resumable_run(reference, tmp_path):
  """A batch scheduler's SIGTERM ends the run as Ctrl-C does: exit code 1, one line naming the
  signal and the last good checkpoints, and --resume writes the uninterrupted run's bytes."""
  out = str(tmp_path / "run")
  proc = _started_past_a_checkpoint(out, subprocess.PIPE)
  proc.send_signal(signal.SIGTERM)
  err = proc.communicate(timeout=120)[1]
  lines = [l for l in err.splitlines() if l.strip() and "Warning" not in l and "warn" not in l]
  assert proc.returncode == 1, err[-2000:]
  assert len(lines) == 1 and lines[0].startswith("error: terminated (SIGTERM); last good "
                                                 "checkpoints: ours step"), lines
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _bytes(out) == _bytes(reference)


def test_time_limit_stops_checkpointed_and_resume_completes_the_run(reference, tmp_path,
                                                                   monkeypatch, capsys):
  out = str(tmp_path / "run")
  argv = TINY + ["--method", "ours", "ref-ppo", "--out", out, "--checkpoint-every", "400",
                 "--time-limit", "60"]
  starts = []

  def allows(self, chunk_s):  # the clock runs out after 3 chunks of each process
    starts.append(chunk_s)
    return len(starts) <= 3

  monkeypatch.setattr(cli.Clock, "allows", allows)
  # Stop 1 inside ours, between checkpoints (600 is saved for the stop); stop 2 inside ref-ppo,
  # on a checkpoint step (400, already saved).
  assert cli.main("PointMaze", argv) == cli.EXIT_TIME_LIMIT
  assert "ours: stopped at step 600 of 800" in capsys.readouterr().out
  assert sorted(os.listdir(os.path.join(out, "checkpoints", "ours"))) == ["400", "600"]
  starts.clear()
  assert cli.main("PointMaze", ["--resume", out, "--no-progress", "--time-limit", "60"]) == 3
  assert "ref-ppo: stopped at step 400 of 800" in capsys.readouterr().out
  starts.clear()
  monkeypatch.undo()
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _rows(out) == _rows(reference)
  assert _bytes(out) == _bytes(reference)  # one line ending, whatever the resume history


def test_cpu_devices_cannot_change_once_jax_runs(tmp_path, capsys):
  """This process's JAX runs on one CPU device (conftest.py); tests/test_sharding.py starts a
  process on two."""
  import jax
  assert jax.device_count() == 1  # JAX started here, whatever ran before in this worker
  with pytest.raises(SystemExit) as err:
    cli.main("PointMaze", ["--cpu-devices", "2", "--out", str(tmp_path / "run")])
  assert err.value.code == 2
  assert "--cpu-devices 2: JAX has already started with 1 CPU device" in capsys.readouterr().err
  assert not (tmp_path / "run").exists()


def test_resume_uses_the_cpu_device_count_the_run_trained_on(tmp_path, monkeypatch):
  """A run split over 2 CPU devices continues on 2 (its rounding depends on the split), one
  on a GPU leaves the CPU count alone, and a new run takes --cpu-devices."""
  calls = []
  monkeypatch.setattr(cli.run, "use_cpu_devices", calls.append)
  for name, payload in (("cpu2", {"platform": "cpu", "device_count": 2}),
                        ("gpu", {"platform": "gpu", "device_count": 4})):
    (tmp_path / name).mkdir()
    (tmp_path / name / "config.json").write_text(json.dumps(payload))
    cli._use_cpu_devices(argparse.Namespace(resume=str(tmp_path / name), cpu_devices=None))
  cli._use_cpu_devices(argparse.Namespace(resume=None, cpu_devices=3))
  cli._use_cpu_devices(argparse.Namespace(resume=None, cpu_devices=None))
  assert calls == [2, 3]


def test_clock_estimates_the_next_chunk_by_the_last(tmp_path):
  path = str(tmp_path / "timing.json")
  clock = cli.Clock.starting_now(100.0, path)
  assert clock.allows(None) and clock.allows(99.0) and not clock.allows(101.0)
  clock.saw_first_chunk(150.0)  # a method's first chunk compiles: estimated by the longest one
  clock.saw_first_chunk(20.0)
  assert not clock.allows(None)
  # A resumed process knows it before its first chunk.
  assert cli.Clock.starting_now(100.0, path).first_chunk_s == 150.0
  assert not cli.Clock.starting_now(100.0, path).allows(None)
  assert cli.Clock.starting_now(None).allows(1e9)


@pytest.mark.parametrize("argv,message", [
    (["--method", "sac"], "invalid choice"),
    (["--preset", "huge"], "invalid choice"),
    (["--top.alpha", "0", "0.4"], "--top.alpha: expected 3 arguments"),
    (["--c", "-10"], "c must be >= 1"),
    (["--c", "0"], "c must be >= 1"),  # not a ZeroDivisionError sizing the buffers
    (["--sweep", "c=0"], "c must be >= 1"),
    (["--num_envs", "0"], "num_envs must be >= 1"),
    (["--top.horizon", "-50"], "top.horizon must be >= 1"),
    (["--homeostasis.rho", "1.5"], "rho must be in (0, 1]"),
    (["--top.s_o", "0.6", "0.6", "2"], "top.s_o entries must be in"),
    (["--steps", "1001", "--chunk", "1000"], "must be a multiple of --chunk"),
    (["--horizon", "5"], "unrecognized arguments"),
    (["--low.batch_size", "many"], "invalid int value"),
    (["--cpu-devices", "0"], "--cpu-devices must be >= 1"),
])
def test_bad_input_exits_2_naming_the_field_and_writes_nothing(tmp_path, capsys, argv, message):
  out = tmp_path / "run"
  with pytest.raises(SystemExit) as err:
    cli.main("PointMaze", argv + ["--out", str(out)])
  assert err.value.code == 2
  assert message in capsys.readouterr().err
  assert not out.exists()


def test_existing_output_is_never_overwritten(reference, capsys):
  before = _rows(reference)
  with pytest.raises(SystemExit) as err:
    cli.main("PointMaze", TINY + ["--method", "ours", "--out", reference])
  assert err.value.code == 2 and "--resume" in capsys.readouterr().err
  assert _rows(reference) == before


def test_help_lists_every_field_with_its_default(capsys):
  with pytest.raises(SystemExit):
    cli.main("AntPush", ["--help"])
  text = capsys.readouterr().out
  for flag in ("--top.alpha", "--homeostasis.rho", "--low.batch_size", "--middle_ppo.std_init",
               "--num_envs", "--resume", "--preset"):
    assert flag in text
  assert "(default: 0.0 0.4 0.7;" in text  # as typed on the command line


def test_plots_are_drawn_from_a_run(reference, tmp_path):
  from experiments import curves, plot

  assert plot.main([reference, "--out", str(tmp_path)]) == 0
  names = sorted(os.listdir(tmp_path))
  assert names == ["pointmaze_iqm.pdf", "pointmaze_iqm.png", "pointmaze_modes.pdf",
                   "pointmaze_modes.png", "pointmaze_seeds.pdf", "pointmaze_seeds.png",
                   "pointmaze_success.pdf", "pointmaze_success.png", "summary.md"]
  assert all(os.path.getsize(tmp_path / n) > 5000 for n in names if n != "summary.md")
  assert "| PointMaze | Ref:PPO | 2 | 800 |" in (tmp_path / "summary.md").read_text()
  steps, mean, lower, upper, n = curves.curves(_rows(reference), "PointMaze", "ours",
                                               "cum_steps_RANDOM")
  assert n == 2 and list(steps) == [200, 400, 600, 800] and lower[-1] <= mean[-1] <= upper[-1]
  assert mean[-1] > 0
  with pytest.raises(SystemExit) as err:
    plot.main([str(tmp_path / "missing")])
  assert err.value.code == 2


def test_first_non_finite_names_seed_and_level():
  from types import SimpleNamespace

  import numpy as np

  from nonmono_jax.core import summary
  from nonmono_jax.host import run

  # the core says what is finite (summary.py), the host which lane and where
  params = {level: {"w": np.ones((3, 4)), "b": np.zeros((3,))}
            for level in ("low", "middle", "top")}
  states = SimpleNamespace(learner_params=lambda: params)
  metrics = {"top/loss": np.zeros(3), "reward": np.zeros(3), "horizon/p_TD3": np.full(3, np.nan)}
  check = lambda: run.first_non_finite(SimpleNamespace(
      reward=metrics["reward"], params_finite=summary.params_finite(states),
      metrics_finite=summary.metrics_finite(states, metrics)))
  assert check() is None
  params["top"]["w"][2, 1] = np.nan
  assert check() == (2, "top")
  metrics["top/loss"][1] = np.inf
  assert check() == (1, "metric top/loss")


def test_non_finite_stops_the_run_after_the_last_good_checkpoint(tmp_path, monkeypatch, capsys):
  from nonmono_jax.host import run

  calls = []

  def fake(summary):  # a NaN appears in the third chunk
    calls.append(1)
    return (1, "middle") if len(calls) == 3 else None

  monkeypatch.setattr(run, "first_non_finite", fake)
  out = tmp_path / "run"
  assert cli.main("PointMaze", TINY + ["--method", "ours", "--out", str(out)]) == 1
  err = capsys.readouterr().err
  assert "NaN or Inf in middle of seed 1 within steps 400-600" in err
  assert "last good checkpoint is step 400" in err
  assert sorted(os.listdir(out / "checkpoints" / "ours")) == ["200", "400"]
  assert max(int(r["env_step"]) for r in _rows(str(out))) == 400


def test_render_writes_a_gif_of_a_trained_policy(reference, tmp_path, capsys):
  from PIL import Image

  from experiments import render

  out = tmp_path / "roll.gif"
  assert render.main([reference, "--method", "ref-ppo", "--seed", "1", "--out", str(out),
                      "--max-frames", "20"]) == 0
  assert "20 frames" in capsys.readouterr().out
  with Image.open(out) as im:
    assert im.n_frames == 20 and im.size[0] > 200
  roll = render.rollout(reference, "ours", 0)
  assert roll["pos"].shape == (101, 3) and roll["goal"].shape == (101, 3)
  with pytest.raises(SystemExit) as err:
    render.main([reference, "--method", "hiro"])
  assert err.value.code == 2


def _with_eval(run, scores):
  """Rewrites run's metrics.csv: S_E of (method, seed) at its k-th evaluation is scores[...][k]."""
  rows, seen = _rows(run), collections.Counter()
  for r in rows:
    if r["eval_success"] != "" and (r["method"], r["seed"]) in scores:
      k = seen[r["method"], r["seed"]]
      seen[r["method"], r["seed"]] += 1
      r["eval_success"] = scores[r["method"], r["seed"]][k]
  with open(os.path.join(run, "metrics.csv"), "w", newline="") as f:
    writer = csv.DictWriter(f, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
  return min(seen.values())


def test_render_picks_the_best_and_the_worst_seed(reference, tmp_path, capsys):
  from experiments import render

  run = str(tmp_path / "run")
  shutil.copytree(reference, run)
  n = 4  # evaluations per seed in the tiny run
  assert _with_eval(run, {("ours", "0"): [0.9] * (n - 1) + [0.2],
                          ("ours", "1"): [0.0] * (n - 1) + [0.6],
                          ("ref-ppo", "0"): [0.0] * (n - 1) + [0.4],
                          ("ref-ppo", "1"): [0.8] + [0.0] * (n - 2) + [0.4]}) == n
  assert render.ranked_seed(run, "ours", "best")[:2] == (1, 0.6)  # by the final S_E
  assert render.ranked_seed(run, "ours", "worst")[:2] == (0, 0.2)
  kept = sorted(os.listdir(os.path.join(run, "checkpoints", "ours")), key=int)
  shutil.rmtree(os.path.join(run, "checkpoints", "ours", kept[-1]))  # S_E where it is covered
  assert render.ranked_seed(run, "ours", "best") == (0, 0.9, int(kept[-2]))
  assert render.ranked_seed(run, "ref-ppo", "best")[0] == 1  # a tie: the mean decides
  assert render.ranked_seed(run, "ref-ppo", "worst")[0] == 0
  _with_eval(run, {("ref-ppo", "1"): [0.0] * (n - 1) + [0.4]})
  assert render.ranked_seed(run, "ref-ppo", "best")[0] == 0  # a whole tie: the lower index
  assert render.ranked_seed(run, "ref-ppo", "worst")[0] == 0
  out = tmp_path / "worst.gif"
  assert render.main([run, "--method", "ours", "--seed", "worst", "--out", str(out),
                      "--max-frames", "2"]) == 0
  assert "worst seed: 1 (S_E 0.00" in capsys.readouterr().out and out.exists()
  with pytest.raises(SystemExit) as err:
    render.main([run, "--seed", "median"])
  assert err.value.code == 2


def test_widen_keeps_the_paper_per_env_step():
  from nonmono_jax.host import methods

  def widen(envs_per_seed, grad_steps=None):
    return methods.build_config("paper", "ours", "AntPush", widen={
        "envs_per_seed": envs_per_seed, "grad_steps": grad_steps})

  wide, wspec = widen(64, 8)
  assert (wide.num_envs, wide.low_updates, wide.middle_updates) == (64, 8, 8)
  # gradient samples per env step: 8 x 800 per 64 env steps = the paper's 100 per env step
  assert wide.low.batch_size == wide.middle.batch_size == 800
  assert wide.warmup_steps * 64 >= 100_000 > (wide.warmup_steps - 1) * 64
  assert wide.top.starting_steps * 64 >= 250_000 > (wide.top.starting_steps - 1) * 64
  assert wide.middle_ppo.std_decay_every == -(-250_000 // 64)
  assert wspec.steps * 64 >= 3_150_000 and wspec.steps % wspec.chunk == 0
  assert wspec.checkpoint_every % wspec.chunk == 0
  assert (wide.c, wide.top.horizon, wide.top.train_every) == (10, 50, 400)  # per env
  exact, _ = widen(16)
  assert (exact.low_updates, exact.low.batch_size) == (16, 100)  # U = E: the paper's updates
  with pytest.raises(ValueError, match="--grad-steps must be in"):
    widen(16, 32)
  with pytest.raises(ValueError, match="--envs-per-seed must be >= 1"):
    widen(0)


def test_a_widened_run_resumes_with_its_saved_plan(tmp_path):
  from nonmono_jax.host import folder, plan as plan_lib

  args = cli.make_parser("PointMaze").parse_args(
      ["--method", "ours", "--envs-per-seed", "4", "--grad-steps", "2", "--out", str(tmp_path)])
  plan = cli.plan_from_args("PointMaze", args)
  again = plan_lib.from_json(json.loads(json.dumps(folder.to_json(plan))), str(tmp_path))
  assert again.configs == plan.configs and again.spec == plan.spec and not again.warnings
  assert plan.configs["ours"].num_envs == 4 and plan.spec.steps == 10_000
  with pytest.raises(ValueError, match="--grad-steps needs --envs-per-seed"):
    cli.plan_from_args("PointMaze", cli.make_parser("PointMaze").parse_args(["--grad-steps", "2"]))


def test_sweep_values_are_parsed_by_their_fields_types():
  sweep = cli.parse_sweep([["top.alpha=0,0.4,0.7", "0,0.2,0.35"], ["top.reward_mod=true", "no"],
                           ["c=5", "10"]])
  assert sweep == {"top.alpha": [(0.0, 0.4, 0.7), (0.0, 0.2, 0.35)],
                   "top.reward_mod": [True, False], "c": [5, 10]}
  assert isinstance(sweep["top.alpha"][0][0], float) and isinstance(sweep["c"][0], int)
  for given, message in (([["top.x=1"]], "--sweep top.x: not a config field"),
                         ([["c=1.5"]], "--sweep c: invalid literal"),
                         ([["top.reward_mod=maybe"]], "--sweep top.reward_mod: expected true"),
                         ([["top.alpha"]], "--sweep takes FIELD=VALUE"),
                         ([["c=5"], ["c=6"]], "--sweep c is given twice")):
    with pytest.raises(ValueError) as e:
      cli.parse_sweep(given)
    assert str(e.value).startswith(message), e.value


def test_any_registered_task_runs_through_python_m_experiments():
  env = {**os.environ, "JAX_PLATFORMS": "cpu"}
  ok = subprocess.run([sys.executable, "-m", "experiments", "PointMaze", "--help"], cwd=ROOT,
                      capture_output=True, text=True, env=env)
  assert ok.returncode == 0 and "python -m experiments.pointmaze" in ok.stdout
  bad = subprocess.run([sys.executable, "-m", "experiments", "HalfCheetah"], cwd=ROOT,
                       capture_output=True, text=True, env=env)
  assert bad.returncode == 2 and "unknown task HalfCheetah; tasks: AntPush" in bad.stderr


def _by_hand(weights, x):
  """An MLP in nn.Linear's layout ([w0, b0, ...], weight (out, in)) computed in numpy."""
  for i in range(0, len(weights), 2):
    x = x @ weights[i].T + weights[i + 1]
    x = np.maximum(x, 0) if i < len(weights) - 2 else np.tanh(x)
  return x


def test_cross_eval_exports_the_actors_each_seed_was_evaluated_with(reference):
  """``reference.cross_eval``'s side in this venv: per seed the target actors of the newest
  checkpoint in torch's layout, which computed by hand act as our actors on the probes, the
  scales, and the run's own evaluation at that step; an older step on request."""
  from nonmono_jax.host import programs
  from reference import cross_eval
  out = cross_eval.export(reference, "ours")
  meta = json.loads(str(out["meta"]))
  assert (meta["method"], meta["step"], meta["seeds"]) == ("ours", 800, [0, 1])
  for k in meta["seeds"]:
    for name, inputs in (("low", [out["probe_obs"], out["probe_goal"]]),
                         ("middle", [out["probe_obs"], np.broadcast_to(
                             out["middle_context"], (64, len(out["middle_context"])))])):
      weights = [out[f"seed{k}/{name}/{i}"] for i in range(6)]
      assert weights[0].shape[0] == 16 and weights[1].shape == (16,)
      scale = out[f"{name}_scale"]
      np.testing.assert_allclose(_by_hand(weights, np.concatenate(inputs, 1)) * scale,
                                 out[f"seed{k}/probe_{name}"], rtol=0, atol=1e-5 * scale.max())
  rows = {int(r["seed"]): r for r in _rows(reference)
          if r["method"] == "ours" and int(r["env_step"]) == meta["env_step"]}
  assert len(rows) == 2 and {int(k): v["eval_distance"] for k, v in meta["ours"].items()} == {
      k: float(r["eval_distance"]) for k, r in rows.items()}
  # the target actors (eval_target_networks), which after training are not the online ones
  *_, states = programs.restored(reference, "ours", 600)
  low = states.low.params
  older = cross_eval.export(reference, "ours", step=600)
  assert json.loads(str(older["meta"]))["step"] == 600
  target = np.asarray(low.target_actor["params"]["dense_0"]["kernel"][1]).T
  np.testing.assert_array_equal(older["seed1/low/0"], target)
  assert not np.array_equal(np.asarray(low.actor["params"]["dense_0"]["kernel"][1]).T, target)
  with pytest.raises(ValueError, match="no checkpoint of ours at step 100"):
    cross_eval.export(reference, "ours", step=100)
  with pytest.raises(ValueError, match="the code's actors are 300-300"):
    cross_eval.check_config(programs.saved_method(reference)[0].configs["ours"])
