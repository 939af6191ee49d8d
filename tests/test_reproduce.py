"""``experiments.reproduce``: a run folder re-run here gives its rows, and a changed row is
named."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from experiments import reproduce
from tests_support import CACHE_DIR, ROOT, TINY_RUN


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
  """A tiny HIRO run, made by a process of its own (on this machine type): reproducing it
  here is a new process's compile and run, as a user's would be."""
  out = str(tmp_path_factory.mktemp("made") / "run")
  env = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}
  subprocess.run([sys.executable, "-m", "experiments.pointmaze", *TINY_RUN, "--method", "hiro",
                  "--out", out], cwd=ROOT, env=env, check=True, capture_output=True)
  return out


def test_a_folder_reproduces_on_its_machine_type(folder, capsys):
  assert reproduce.main([folder, "--steps", "400"]) == 0
  out = capsys.readouterr().out
  assert "this host is the same machine type" in out
  assert "hiro: env steps up to 400, 4 rows compared: all equal" in out  # 2 seeds x 2 chunks


def test_a_changed_row_is_named_with_its_step_seed_and_column(folder, tmp_path, capsys):
  changed = str(tmp_path / "changed")
  shutil.copytree(folder, changed)
  path = os.path.join(changed, "metrics.csv")
  lines = open(path).read().splitlines(keepends=True)
  fields = lines[3].split(",")  # env step 400, seed 0
  assert fields[1:4] == ["hiro", "0", "400"]
  fields[7] = "-1.5"  # train_reward
  lines[3] = ",".join(fields)
  open(path, "w").write("".join(lines))
  assert reproduce.main([changed, "--steps", "400"]) == reproduce.EXIT_DIFFER
  report = capsys.readouterr().out.splitlines()[-1]
  assert report.startswith("hiro: env steps up to 400, 4 rows compared: 1 differ, the first at "
                           "env step 400 (seed 0: train_reward -1.5 there, ")


def test_bad_input_is_one_line_and_exit_code_2(folder, tmp_path, capsys):
  assert reproduce.main([str(tmp_path)]) == reproduce.EXIT_BAD_INPUT  # no config.json
  assert reproduce.main([folder, "--method", "ours"]) == reproduce.EXIT_BAD_INPUT
  assert reproduce.main([folder, "--steps", "0"]) == reproduce.EXIT_BAD_INPUT
  err = capsys.readouterr().err.splitlines()
  assert len(err) == 3 and "no config.json" in err[0]
  assert "has no method ours (it has hiro)" in err[1] and "--steps must be positive" in err[2]


def test_a_run_from_before_host_recording_says_so():
  assert "does not record the machine" in reproduce.host_line({"task": "PointMaze"})
  moved = reproduce.host_line({"host": {"cpu": "another CPU", "cpu_family": "1",
                                        "cpu_model": "2", "isa": [], "xla_flags": ""}})
  assert moved.startswith("made on another CPU (family 1, model 2); this host differs (cpu ")


def test_a_resume_at_another_commit_or_machine_type_is_said(folder, tmp_path):
  """The run's sessions (``sessions.jsonl``): its start here; a resume elsewhere is named,
  with where a re-run from step 0 stops repeating its rows."""
  from nonmono_jax.host import folder as folder_lib, provenance
  first, = folder_lib.read_sessions(folder)
  assert not first["resumed"] and first["host"] == provenance.host()
  assert reproduce.moved_line(folder) is None
  moved = str(tmp_path / "moved")
  shutil.copytree(folder, moved)
  here_again = {**first, "resumed": True, "started": "2026-12-07T10:00:00+0000"}
  elsewhere = {**here_again, "started": "2026-12-08T10:00:00+0000",
               "host": {**first["host"], "cpu": "another CPU", "cpu_model": "1"},
               "code": {"commit": "abcdef0123456789", "dirty": False}}
  with open(os.path.join(moved, "sessions.jsonl"), "a") as f:
    f.write(json.dumps(here_again) + "\n" + json.dumps(elsewhere) + "\n" + '{"started": "2026')
  line = reproduce.moved_line(moved)
  assert line.startswith("resumed at commit abcdef0 and on another CPU (family "
                         f"{first['host']['cpu_family']}, model 1) on 2026-12-08T10:00:00+0000: ")
  assert "only up to there" in line
  flags = {**here_again, "host": {**first["host"], "cores": 64, "xla_flags": "--x"}}
  assert provenance.moves([first, flags]) == [  # the core count alone is no other machine type
      "resumed with XLA_FLAGS '--x' on 2026-12-07T10:00:00+0000"]

