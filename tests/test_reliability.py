"""The run folder's promises under bad input and faults (issue 14): one writer, every value
checked before anything is written, fallback to an older checkpoint, one line per failure with
exit code 0 ok / 1 failed run / 2 bad input / 3 time limit."""

import dataclasses
import errno
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from experiments import cli
from nonmono_jax.core import validation
from nonmono_jax.host import folder, rows as rows_lib, run
from tests_support import CACHE_DIR, ROOT, TINY_OVERRIDES, TINY_RUN, TINY_SIZE


def _bytes(out):
  with open(os.path.join(out, "metrics.csv"), "rb") as f:
    return f.read()


def _main(capsys, argv, task="PointMaze"):
  """(exit code, stderr lines, stdout) of the command, run in this process."""
  try:
    code = cli.main(task, argv)
  except SystemExit as e:
    code = e.code
  got = capsys.readouterr()
  return code, [l for l in got.err.splitlines() if l.strip()], got.out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
  """An uninterrupted tiny run of ours (checkpoints 600 and 800 kept)."""
  out = str(tmp_path_factory.mktemp("ref") / "run")
  assert cli.main("PointMaze", TINY_RUN + ["--method", "ours", "--out", out]) == 0
  return out


def _copy(reference, tmp_path):
  out = str(tmp_path / "run")
  shutil.copytree(reference, out)
  return out


# --- 1. one writer ------------------------------------------------------------------------------

@pytest.mark.slow  # starts processes
def test_a_second_writer_exits_2_naming_the_holder_and_a_dead_holder_leaves_no_lock(
    reference, tmp_path, capsys):
  out = str(tmp_path / "run")
  env = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}
  proc = subprocess.Popen([sys.executable, "-m", "experiments.pointmaze", *TINY_RUN,
                           "--method", "ours", "--out", out], cwd=ROOT, env=env,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
  deadline = time.time() + 300
  while time.time() < deadline and not os.path.exists(os.path.join(out, "config.json")):
    time.sleep(0.05)
  code, err, _ = _main(capsys, ["--resume", out, "--no-progress"])
  assert proc.poll() is None, "the first run ended before the second could try"
  assert code == 2 and len(err) == 1 and f"in use by pid {proc.pid}" in err[0]
  proc.send_signal(signal.SIGKILL)  # the holder dies: its lock goes with it
  proc.wait()
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _bytes(out) == _bytes(reference)


# --- 2. every value checked before anything is written ------------------------------------------

@pytest.mark.parametrize("argv,message", [
    (["--goal_range", "nan", "4", "0"], "goal_range[0] must be a finite number"),
    (["--top.alpha", "nan", "0", "0"], "top.alpha[0] must be a finite number"),
    (["--low.policy_noise", "nan"], "low.policy_noise must be a finite number"),
    (["--top.ppo.lr_actor", "inf"], "top.ppo.lr_actor must be a finite number"),
    (["--low.lr_actor", "2"], "low.lr_actor must be in (0, 1]"),
    (["--goal_range", "1e39", "1e39", "0"], "goal_range[0] must fit in a float32"),
    (["--top.alpha", "0", "0.4", "1e39"], "top.alpha[2] must fit in a float32"),
    (["--top.ppo.lr_actor", "1e6"], "top.ppo.lr_actor must be in (0, 1]"),
    (["--middle_ppo.lr_critic", "5"], "middle_ppo.lr_critic must be in (0, 1]"),
    (["--warmup_steps", "3000000000"], "warmup_steps must fit in an int32"),
    (["--low.buffer_size", "2000000000"], "GiB available"),
    (["--seeds", "100000"], "GiB available"),
    (["--episode-length", "2000000000"], "GiB available"),
    (["--c", "7"], "(from --c 7"),
    (["--time-limit", "nan"], "--time-limit must be a positive number"),
    (["--out", ""], "--out must not be empty"),
])
def test_bad_values_exit_2_in_one_line_before_the_folder_exists(tmp_path, capsys, argv, message):
  out = tmp_path / "run"
  argv = argv + (["--out", str(out)] if "--out" not in argv else [])
  code, err, _ = _main(capsys, argv)
  assert code == 2 and len(err) == 1 and message in err[0], err
  assert not out.exists()


def test_the_memory_check_counts_the_compiled_program(tmp_path, capsys, monkeypatch):
  """A run whose train state fits but whose compiled chunk (state, temporaries, evaluation)
  does not is refused before its folder exists, by XLA's count of the program."""
  from nonmono_jax.host import plan as plan_lib, programs as programs_lib
  probe = plan_lib.new_run("PointMaze", ["ours"], preset="quick",
                           overrides=TINY_OVERRIDES, run=TINY_SIZE)
  programs = programs_lib.Programs(probe)
  state = programs_lib.state_bytes(programs, ["ours"])
  evals = 2 * 2 * 100 * programs_lib.EVAL_RECORD_BYTES  # seeds x episodes x steps
  program = programs.trainer("ours").program_bytes()["total"]
  assert program > state + evals  # temporaries come on top of the state
  monkeypatch.setattr(programs_lib, "available_bytes", lambda: int((state + evals) * 1.02))
  out = tmp_path / "run"
  code, err, _ = _main(capsys, TINY_RUN + ["--method", "ours", "--out", str(out)])
  assert code == 2 and len(err) == 1 and "XLA's count of the compiled chunk" in err[0], err
  assert not out.exists()
  monkeypatch.setattr(programs_lib, "available_bytes", lambda: int(program * 1.2))
  programs_lib.check_memory(probe, programs)  # fits: no error


def test_the_validator_walks_any_config_by_its_type_hints():
  @dataclasses.dataclass(frozen=True)
  class Inner:
    rate: float = 0.1
    limit: float = dataclasses.field(default=float("inf"), metadata={"infinite_ok": True})
    sizes: tuple[int, ...] = (1, 2)

  @dataclasses.dataclass(frozen=True)
  class Outer:
    inner: Inner = Inner()
    steps: int = 5

  validation.check(Outer())
  for bad, message in ((Outer(inner=Inner(rate=float("inf"))), "inner.rate must be a finite"),
                       (Outer(inner=Inner(limit=float("nan"))), "inner.limit must be a finite"),
                       (Outer(inner=Inner(sizes=(1, 2**31))), "inner.sizes[1] must fit"),
                       (Outer(steps=-2**31 - 1), "steps must fit in an int32")):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
      validation.check(bad)


# --- 3. a corrupted latest checkpoint ------------------------------------------------------------

def _truncate_data(step_dir):
  for root, _, files in os.walk(os.path.join(step_dir, "default")):
    for name in files:
      if "ocdbt.process" in root and os.sep + "d" in root:
        with open(os.path.join(root, name), "r+b") as f:
          f.truncate(3)


def _remove_manifest(step_dir):
  for root, _, files in os.walk(step_dir):
    for name in files:
      if name == "manifest.ocdbt":
        os.remove(os.path.join(root, name))


def _empty(step_dir):
  shutil.rmtree(step_dir)
  os.makedirs(step_dir)


@pytest.mark.parametrize("corrupt,bad,good", [(_truncate_data, "800", 600),
                                               (_remove_manifest, "800", 600),
                                               (_empty, "800", 600),
                                               (os.makedirs, "1000", 800)])  # a junk folder
def test_resume_falls_back_to_the_newest_checkpoint_that_restores(reference, tmp_path, capsys,
                                                                   corrupt, bad, good):
  out = _copy(reference, tmp_path)
  ckpts = os.path.join(out, "checkpoints", "ours")
  corrupt(os.path.join(ckpts, bad))
  code, err, stdout = _main(capsys, ["--resume", out, "--no-progress"])
  assert code == 0, err
  assert f"skipped checkpoint {ckpts}/{bad}" in stdout
  assert f"ours: resumed from step {good}" in stdout
  assert _bytes(out) == _bytes(reference)  # a lost last chunk ran again
  assert len(os.listdir(ckpts + ".broken")) == 1  # kept aside, not deleted


def test_no_checkpoint_restoring_is_one_line(reference, tmp_path, capsys):
  out = _copy(reference, tmp_path)
  for step in ("600", "800"):
    _empty(os.path.join(out, "checkpoints", "ours", step))
  code, err, _ = _main(capsys, ["--resume", out, "--no-progress"])
  assert code == 2 and len(err) == 1 and "no checkpoint in" in err[0] and "restores" in err[0]


# --- 4. what --resume may change -----------------------------------------------------------------

@pytest.mark.parametrize("task,argv,message", [
    ("PointMaze", ["--steps", "1600"], "--steps cannot change on --resume"),
    ("PointMaze", ["--low.lr_actor", "0.5", "--method", "hiro"],
     "--low.lr_actor, --method cannot change"),
    ("PointPush", [], "it is a PointMaze run, not PointPush"),
])
def test_resume_refuses_what_cannot_change(reference, capsys, task, argv, message):
  before = _bytes(reference)
  code, err, _ = _main(capsys, ["--resume", reference, *argv], task)
  assert code == 2 and len(err) == 1 and message in err[0], err
  assert _bytes(reference) == before


# --- 5. one line instead of a traceback ----------------------------------------------------------

def test_bad_out_paths_are_one_line(tmp_path, capsys):
  a_file = tmp_path / "file"
  a_file.write_text("x")
  for out, message in ((a_file, "exists and is not a folder"),
                       (a_file / "run", "cannot create the folder"),
                       (tmp_path / ("x" * 300), "is longer than 255 bytes"),
                       (tmp_path / "/".join(["y" * 200] * 21), "more than the 4095")):
    code, err, _ = _main(capsys, ["--out", str(out)])
    assert code == 2 and len(err) == 1 and message in err[0], err
  assert sorted(os.listdir(tmp_path)) == ["file"]  # no folder made on the way


@pytest.mark.parametrize("edit,message", [
    (lambda c: c["configs"]["ours"]["low"].update(batch_size="8"),
     "configs.ours: low.batch_size must be an integer, got '8'"),
    (lambda c: c["configs"]["ours"]["top"].update(alpha=[0, "0.4", 0.7]),
     "configs.ours: top.alpha[1] must be a number, got '0.4'"),
    (lambda c: c["configs"]["ours"].update(switch=1),
     "configs.ours: switch must be a string, got 1"),
])
def test_a_wrong_type_in_config_json_is_named(reference, tmp_path, capsys, edit, message):
  out = _copy(reference, tmp_path)
  path = os.path.join(out, "config.json")
  payload = folder.read_json(path)
  edit(payload)
  folder.write_json(path, payload)
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and message in err[0], err


def test_odd_files_in_a_run_folder_are_one_line(reference, tmp_path, capsys):
  """metrics.csv a folder, checkpoints a file: refused in one line, not a traceback."""
  out = _copy(reference, tmp_path)
  os.remove(os.path.join(out, "metrics.csv"))
  os.mkdir(os.path.join(out, "metrics.csv"))
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and "metrics.csv: cannot be read (Is a directory)" in err[0]
  out = _copy(reference, tmp_path / "b")
  shutil.rmtree(os.path.join(out, "checkpoints"))
  open(os.path.join(out, "checkpoints"), "w").close()
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and "checkpoints is not a folder" in err[0], err


def test_a_leftover_orbax_temporary_folder_is_not_kept_as_a_checkpoint(reference, tmp_path,
                                                                        capsys):
  """A kill during a save leaves orbax's temporary folder; the resumed run removes it, and
  keeps its two newest checkpoints, as a run that never stopped."""
  out = _copy(reference, tmp_path)
  ckpts = os.path.join(out, "checkpoints", "ours")
  shutil.rmtree(os.path.join(ckpts, "800"))
  shutil.copytree(os.path.join(ckpts, "600"), os.path.join(ckpts, "800.orbax-checkpoint-tmp-1"))
  code, err, _ = _main(capsys, ["--resume", out, "--no-progress"])
  assert code == 0, err
  assert sorted(os.listdir(ckpts)) == ["600", "800"]
  assert _bytes(out) == _bytes(reference)


@pytest.mark.parametrize("edit,message", [
    (lambda c: [c], "config.json: expected a JSON object, got a list"),
    (lambda c: {k: v for k, v in c.items() if k != "run"}, "config.json: the key 'run' is"),
    (lambda c: {**c, "run": {**c["run"], "chunk": 0}}, "config.json: --chunk must be >= 1"),
])
def test_a_malformed_config_json_is_one_line(reference, tmp_path, capsys, edit, message):
  out = _copy(reference, tmp_path)
  path = os.path.join(out, "config.json")
  folder.write_json(path, edit(folder.read_json(path)))
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and message in err[0], err
  from experiments import render

  with pytest.raises(SystemExit) as e:
    render.main([out])
  assert e.value.code == 2


def test_render_to_an_unwritable_path_is_one_line(reference, tmp_path, capsys):
  from experiments import render

  for argv, message in (([reference, "--max-frames", "0"], "--max-frames must be >= 1"),
                        ([reference, "--max-frames", "-5"], "--max-frames must be >= 1"),
                        ([reference, "--method", ""], "method '' is not in this run")):
    with pytest.raises(SystemExit) as e:
      render.main(argv)
    err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert e.value.code == 2 and len(err) == 1 and message in err[0], err

  for out in (tmp_path / "no" / "such" / "a.gif", tmp_path):  # no folder; a folder, not a file
    with pytest.raises(SystemExit) as e:
      render.main([reference, "--out", str(out)])
    err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert e.value.code == 2 and len(err) == 1 and "cannot write" in err[0], err


def test_a_broken_metrics_file_or_a_missing_one_is_one_line(reference, tmp_path, capsys):
  out = _copy(reference, tmp_path)
  path = os.path.join(out, "metrics.csv")
  with open(path, "rb") as f:
    lines = f.read().split(b"\n")
  with open(path, "wb") as f:
    f.write(b"\n".join([b"not,a,header"] + lines[1:]))
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and "metrics.csv: the header is not" in err[0], err
  os.remove(path)  # the rows before the checkpoints would be lost: refused, not rebuilt
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and "metrics.csv is missing" in err[0], err


@pytest.mark.parametrize("edit,message", [
    (lambda rows: [], "ours has 0 rows up to env step 800, where its checkpoint needs 8"),
    (lambda rows: rows[:3] + rows[4:], "has 7 rows up to env step 800, where its checkpoint "
                                       "needs 8 (one per seed and chunk); the first wrong one: "
                                       "seed 0 at env step 600 where seed 1 at 400 belongs"),
    (lambda rows: rows[:5] + rows[4:], "has 9 rows"),
    (lambda rows: rows[:6], "the first wrong one: seed 0 at env step 800 is missing"),
])
def test_resume_refuses_rows_that_do_not_match_the_checkpoint(reference, tmp_path, capsys,
                                                              edit, message):
  """A header-only file, a row deleted or doubled, a chunk's rows gone while its checkpoint
  stays: resuming would lose or double rows, so it is refused, and the file left as it is."""
  out = _copy(reference, tmp_path)
  path = os.path.join(out, "metrics.csv")
  with open(path, "rb") as f:
    header, *rows = f.read().decode().splitlines()
  edited = "\n".join([header] + edit(rows)) + "\n"
  with open(path, "w") as f:
    f.write(edited)
  code, err, _ = _main(capsys, ["--resume", out])
  assert code == 2 and len(err) == 1 and message in err[0], err
  assert open(path).read() == edited


@pytest.mark.slow  # starts processes
def test_another_runs_checkpoint_is_one_line_to_the_end_of_the_process(reference, tmp_path):
  """orbax's failed reads leave coroutines and log records that Python printed after the
  command's line, some when the process exited: run in a process of its own, the resume and
  the render of a folder holding another run's checkpoint say one line, nothing after it."""
  other = str(tmp_path / "other")
  argv = TINY_RUN + ["--method", "ours", "--low.hidden", "32", "32", "--steps", "400"]
  assert cli.main("PointMaze", argv + ["--out", other]) == 0
  out = _copy(reference, tmp_path)
  ckpts = os.path.join(out, "checkpoints", "ours")
  shutil.rmtree(ckpts)
  shutil.copytree(os.path.join(other, "checkpoints", "ours"), ckpts)
  env = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}
  for command in (["experiments.pointmaze", "--resume", out], ["experiments.render", out]):
    done = subprocess.run([sys.executable, "-m", *command], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    lines = [l for l in done.stderr.splitlines() if l.strip()]
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-3000:]
    assert "no checkpoint in" in lines[0] and "restores" in lines[0]


def test_a_full_disk_is_one_line_and_keeps_the_last_checkpoint(reference, tmp_path, monkeypatch,
                                                                capsys):
  append, calls = rows_lib.MetricsFile.append, []

  def full(self, rows):  # the disk fills up in the third chunk
    calls.append(1)
    if len(calls) == 3:
      raise OSError(errno.ENOSPC, "No space left on device", self.path)
    append(self, rows)

  monkeypatch.setattr(rows_lib.MetricsFile, "append", full)
  out = str(tmp_path / "run")
  code, err, _ = _main(capsys, TINY_RUN + ["--method", "ours", "--out", out])
  assert code == 1 and len(err) == 1, err
  assert "the disk is full (writing" in err[0] and "last good checkpoints: ours step 400" in err[0]
  monkeypatch.undo()
  assert cli.main("PointMaze", ["--resume", out, "--no-progress"]) == 0
  assert _bytes(out) == _bytes(reference)


def test_plot_says_what_it_cannot_draw(reference, tmp_path, capsys):
  """A run with no rows yet, and a NaN in a row: one line naming the file (and the line)."""
  from experiments import plot

  out = _copy(reference, tmp_path)
  path = os.path.join(out, "metrics.csv")
  with open(path) as f:
    header, *rows = f.read().splitlines()
  with open(path, "w") as f:
    f.write(header + "\n")
  with pytest.raises(SystemExit) as e:
    plot.main([out])
  err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
  assert e.value.code == 2 and len(err) == 1 and "no rows yet" in err[0] and path in err[0]
  cells = rows[1].split(",")
  cells[header.split(",").index("eval_return")] = "nan"
  with open(path, "w") as f:
    f.write("\n".join([header, rows[0], ",".join(cells)] + rows[2:]) + "\n")
  with pytest.raises(SystemExit) as e:
    plot.main([out])
  err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
  assert e.value.code == 2 and f"{path}: line 3: eval_return is nan" in err[0], err


def test_plot_skips_a_half_written_last_line_and_refuses_a_broken_file(reference, tmp_path,
                                                                        capsys):
  from experiments import plot

  out = _copy(reference, tmp_path)
  with open(os.path.join(out, "metrics.csv"), "ab") as f:
    f.write(b"PointMaze,ours,0,1000,0.5,")  # a kill in the middle of a row
  assert plot.main([out, "--out", str(tmp_path / "fig"), "--table"]) == 0
  assert "| PointMaze | Ours | 2 | 800 |" in capsys.readouterr().out
  with open(os.path.join(out, "metrics.csv"), "wb") as f:
    f.write(b"task,method\nPointMaze,ours\n")
  with pytest.raises(SystemExit) as e:
    plot.main([out, "--out", str(tmp_path / "fig2")])
  err = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
  assert e.value.code == 2 and len(err) == 1 and "metrics.csv: the header" in err[0]
  assert not os.path.exists(tmp_path / "fig2")


# --- 6. --time-limit always makes progress -------------------------------------------------------

def test_a_too_short_time_limit_still_advances_a_chunk_per_process(reference, tmp_path, capsys):
  out = str(tmp_path / "run")
  argv = TINY_RUN + ["--method", "ours", "--out", out, "--time-limit", "1e-6"]
  steps = []
  for _ in range(4):
    code, _, stdout = _main(capsys, argv if not steps else
                            ["--resume", out, "--no-progress", "--time-limit", "1e-6"])
    steps.append(max(int(r["env_step"]) for r in rows_lib.MetricsFile(
        os.path.join(out, "metrics.csv")).read()))
    assert code == (3 if len(steps) < 4 else 0)
  assert steps == [200, 400, 600, 800]
  assert _bytes(out) == _bytes(reference)


# --- 7, 8. line endings; the first chunk failing -------------------------------------------------

def test_metrics_use_one_line_ending(reference):
  assert b"\r" not in _bytes(reference)


def test_a_failing_first_chunk_says_there_is_no_checkpoint(tmp_path, monkeypatch, capsys):
  monkeypatch.setattr(run, "first_non_finite", lambda summary: (0, "low"))
  code, err, _ = _main(capsys, TINY_RUN + ["--method", "ours", "--out", str(tmp_path / "r")])
  assert code == 1 and len(err) == 1 and "no checkpoint was saved before it" in err[0], err


def test_a_swallowed_ctrl_c_still_stops_the_run_after_the_chunk(tmp_path, monkeypatch, capsys):
  check, calls = run.first_non_finite, []

  def swallowing(summary):  # Ctrl-C inside a callback that ignores exceptions
    calls.append(1)
    if len(calls) == 2:
      try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1)
      except KeyboardInterrupt:
        pass
    return check(summary)

  monkeypatch.setattr(run, "first_non_finite", swallowing)
  out = str(tmp_path / "run")
  code, err, _ = _main(capsys, TINY_RUN + ["--method", "ours", "--out", out])
  assert code == 1 and len(err) == 1 and err[0].startswith("error: interrupted"), err
  assert len(calls) == 2 and "ours step 400" in err[0]


def test_a_remembered_ctrl_c_ends_with_its_command(tmp_path, monkeypatch, capsys):
  # A Ctrl-C remembered during one command must not stop a later library run in the same
  # process (a notebook, or this test session): run_method checks the flag after each chunk.
  test_a_swallowed_ctrl_c_still_stops_the_run_after_the_chunk(tmp_path, monkeypatch, capsys)
  monkeypatch.undo()
  plan = run.new_run("PointMaze", ["ours"], preset="quick", out=str(tmp_path / "next"),
                     run=TINY_SIZE, overrides=TINY_OVERRIDES)
  with run.open_folder(plan):
    results = list(run.run_method(plan, "ours"))
  assert [r.step for r in results] == [200, 400, 600, 800]
