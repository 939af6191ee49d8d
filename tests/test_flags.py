"""The command's first seconds: --help and bad flags before JAX loads, help text and allowed values
for every flag, task names in any case, the start line, and Ctrl-C at any moment of start-up."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from experiments import cli, flags
from nonmono_jax.core import config as config_lib
from nonmono_jax.host import methods, run
from tests_support import CACHE_DIR, ROOT, TINY_RUN


ENV = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}


def _command(*args, **kwargs):
  env = ENV
  return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, env=env,
                        cwd=kwargs.get("cwd", ROOT), timeout=120)


def test_help_and_bad_flags_load_no_jax():
  """What --help needs (the flags of an ant task, from the config's declarations) imports
  neither JAX nor MJX: it answers in a fraction of a second (benchmarks/help_time.py)."""
  code = ("import sys; from experiments import flags, launch; "
          "flags.make_parser('AntPush').format_help(); flags.make_parser('PointMaze'); "
          "print(sorted(m for m in ('jax', 'jaxlib', 'mujoco.mjx', 'brax', 'flax', 'envs.ant_maze')"
          " if m in sys.modules))")
  r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                     env={**os.environ, "PYTHONPATH": ROOT}, timeout=60)
  assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
  r = _command("experiments.antpush", "--help")
  assert r.returncode == 0 and "--top.alpha" in r.stdout and not r.stderr, r.stderr


def test_every_flag_has_its_help_and_one_default():
  text = flags.make_parser("AntPush").format_help()
  helps = {a.dest: a.help for a in flags.make_parser("AntPush")._actions}
  assert all(h and h.strip() for h in helps.values()), [d for d, h in helps.items() if not h]
  for dest, h in helps.items():
    assert h.count("default:") <= 1, (dest, h)
  assert "FIELD:" not in text and "(default: None)" not in text
  # allowed values come from the field's declaration (config.choice)
  assert "--switch {none,top,homeostasis}" in text and "--low.init {lecun,torch}" in text
  assert "--top.alpha FLOAT FLOAT FLOAT" in text and "--c INT" in text
  # a default as each method and preset has it, not one value for all
  noise = helps["field:middle_goal_noise"]
  assert "default: 0.0; 1.0 for hiro" in noise, noise
  assert "--preset quick: 1000" in helps["field:warmup_steps"]
  assert "only for ours, ours-no-loss-mod" in helps["field:top.alpha"]


def test_every_config_field_says_what_it_is():
  """The help text is the comment each field is declared with: a field without one fails."""
  missing = [name for name, _, f, owner in flags.fields(config_lib.AgentConfig)
             if not flags.field_docs(owner).get(f.name)]
  assert not missing, missing


def test_an_empty_tuple_flag_clears_it():
  args = flags.make_parser("AntPush").parse_args(["--eval_extra"])
  assert vars(args)["field:eval_extra"] == []
  plan = cli.plan_from_args("AntPush", args)
  assert all(c.eval_extra == () for c in plan.configs.values())


def test_task_names_in_any_case():
  assert flags.resolve_task("antpush") == "AntPush" == flags.resolve_task("ANTPUSH")
  r = _command("experiments", "pointmaze", "--help")
  assert r.returncode == 0 and "python -m experiments.pointmaze" in r.stdout
  r = _command("experiments", "antpsh", "--preset", "quick")
  assert r.returncode == 2 and r.stderr.strip().splitlines() == [
      "python -m experiments: error: unknown task antpsh; tasks: "
      + ", ".join(methods.TASKS)], r.stderr
  r = _command("experiments")
  assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_the_start_line_says_the_size_and_how_to_run_short(tmp_path):
  paper = run.new_run("AntPush", ["ours", "hiro"], out=str(tmp_path / "p"))
  lines = cli.start_lines(paper)
  assert lines[0].startswith("AntPush: ours, hiro x 5 seeds x 3150000 steps = 31.5M env steps "
                             "(paper preset, c physics, mujoco200 contacts)"), lines
  assert "--preset quick" in lines[1] and "estimated after its first chunk" in lines[1]
  quick = run.new_run("PointMaze", ["ours"], preset="quick", out=str(tmp_path / "q"))
  assert len(cli.start_lines(quick)) == 1
  assert len(cli.start_lines(paper, resumed=True)) == 1


def test_durations_read_as_a_person_says_them():
  assert [run.duration(s) for s in (4.4, 99, 700, 3 * 3600 + 1200, 3 * 86400 + 7200)] == [
      "4 s", "99 s", "12 min", "3 h 20 min", "3 d 2 h"]


# --- Ctrl-C at any moment of start-up -------------------------------------------------------------

def _interrupted_at(out, when, *extra):
  """A quick point run given SIGINT ``when`` (seconds, or a line of its output to wait for
  and then 0.5 s more): its exit code, stderr lines and stdout."""
  env = ENV
  proc = subprocess.Popen([sys.executable, "-m", "experiments.pointmaze", "--preset", "quick",
                           "--out", out, "--no-progress", *extra], cwd=ROOT, env=env,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
  seen = ""
  if isinstance(when, str):
    while when not in seen:
      line = proc.stdout.readline()
      assert line, f"ended before {when!r}: {proc.stderr.read()[-2000:]}"
      seen += line
    when = 0.5
  time.sleep(when)
  proc.send_signal(signal.SIGINT)
  out_text, err = proc.communicate(timeout=60)
  lines = [l for l in err.splitlines() if l.strip() and "arning" not in l]
  return proc.returncode, lines, seen + out_text


def _nothing_half_written(out):
  """The folder is absent, or a run folder that --resume takes: config.json whole, no
  temporary file."""
  if not os.path.exists(out):
    return
  names = {os.path.join(d, n) for d, _, files in os.walk(out) for n in files}
  assert not [n for n in names if n.endswith(".tmp")], names
  with open(os.path.join(out, "config.json")) as f:
    assert json.load(f)["task"] == "PointMaze"


@pytest.mark.parametrize("seconds", [0.15, 0.6, 1.5])
def test_ctrl_c_during_imports_and_checks_is_one_line(tmp_path, seconds):
  out = str(tmp_path / "run")
  code, lines, _ = _interrupted_at(out, seconds)
  assert code == 1 and len(lines) == 1, lines
  assert lines[0] in ("error: interrupted during start-up: nothing was written",
                      f"error: interrupted; last good checkpoints: ours none; continue with "
                      f"--resume {out}"), lines
  _nothing_half_written(out)


def test_ctrl_c_while_compiling_is_one_line_at_once(tmp_path):
  """Python takes a signal only between bytecodes: during XLA's compile the watchdog says the
  line (interrupts.GRACE_S) instead of waiting for the compile to end."""
  out = str(tmp_path / "run")
  t = time.monotonic()
  code, lines, printed = _interrupted_at(out, "compiling the training program")
  assert code == 1 and lines == [f"error: interrupted; last good checkpoints: ours none; "
                                 f"continue with --resume {out}"], (lines, printed)
  assert time.monotonic() - t < 30 and "compiled in" not in printed
  _nothing_half_written(out)


@pytest.mark.slow  # compiles and trains a chunk
def test_ctrl_c_after_a_chunk_keeps_its_rows_and_checkpoint(tmp_path):
  out = str(tmp_path / "run")
  code, lines, printed = _interrupted_at(out, "ours step 200/", *TINY_RUN)
  assert code == 1 and len(lines) == 1, (lines, printed)
  assert lines[0].startswith("error: interrupted; last good checkpoints: ours step"), lines
  _nothing_half_written(out)
  r = _command("experiments.pointmaze", "--resume", out, "--no-progress")
  assert r.returncode == 0 and "resumed from step" in r.stdout, r.stderr
