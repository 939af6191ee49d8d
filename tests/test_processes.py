"""One run over several processes (``--distributed``, ``nonmono_jax.host.processes``): 2 local
processes with 1 CPU device each write the run folder that 1 process with 2 CPU devices
writes, bit for bit; a killed process stops the other with one line, and ``--resume``
finishes the run."""

import csv
import os
import socket
import subprocess
import sys
import time

import pytest

from tests_support import CACHE_DIR, ROOT, TINY_RUN

pytestmark = pytest.mark.slow  # each test starts 2-4 processes that compile

ENV = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR}
RUN = [sys.executable, "-m", "experiments.pointmaze"]


def _port() -> int:
  with socket.socket() as s:
    s.bind(("localhost", 0))
    return s.getsockname()[1]


def _processes(argv, n=2, port=None):
  """``n`` processes of one run (1 CPU device each), started together."""
  port = port or _port()
  return [subprocess.Popen(RUN + argv + ["--distributed", "--coordinator", f"localhost:{port}",
                                         "--num-processes", str(n), "--process-id", str(i)],
                           cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True) for i in range(n)]


def _finish(procs, timeout=600):
  return [(p.wait(timeout), *p.communicate()) for p in procs]


def _rows(out):
  with open(os.path.join(out, "metrics.csv"), newline="") as f:
    return list(csv.DictReader(f))


def test_two_processes_write_what_one_process_with_two_devices_writes(tmp_path):
  one, two = str(tmp_path / "one"), str(tmp_path / "two")
  argv = TINY_RUN + ["--method", "ours", "--cpu-devices", "1"]
  ref = subprocess.run(RUN + TINY_RUN + ["--method", "ours", "--cpu-devices", "2", "--out", one],
                       cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=600)
  assert ref.returncode == 0, ref.stderr[-2000:]
  results = _finish(_processes(argv + ["--out", two]))
  assert [code for code, _, _ in results] == [0, 0], [err[-2000:] for _, _, err in results]
  with open(os.path.join(one, "metrics.csv"), "rb") as a, \
      open(os.path.join(two, "metrics.csv"), "rb") as b:
    assert a.read() == b.read()  # the same lanes per device compute the same bits
  import json
  config = json.load(open(os.path.join(two, "config.json")))
  assert config["processes"] == 2 and config["device_count"] == 2
  # Process 0 owns the folder and the progress lines; process 1 writes nothing of its own.
  own = lambda text: [l for l in text.splitlines() if not l.startswith("[Gloo]")]
  assert "done:" in results[0][1] and own(results[1][1]) == []
  assert sorted(os.listdir(two)) == sorted(os.listdir(one))
  # A run made by 2 processes resumes with 2, and says so to one.
  alone = subprocess.run(RUN + ["--resume", two], cwd=ROOT, env=ENV, capture_output=True,
                         text=True, timeout=300)
  assert alone.returncode == 2
  assert "made by 2 process(es), this is 1: resume it with --distributed with 2" in alone.stderr


def test_a_killed_process_stops_the_other_with_one_line_and_resume_finishes(tmp_path):
  out = str(tmp_path / "run")
  argv = TINY_RUN + ["--method", "hiro", "--cpu-devices", "1", "--steps", "6000"]
  procs = _processes(argv + ["--out", out])
  deadline = time.time() + 300
  ckpt = os.path.join(out, "checkpoints", "hiro", "400")
  while not os.path.isdir(ckpt) and time.time() < deadline and procs[0].poll() is None:
    time.sleep(0.2)
  assert os.path.isdir(ckpt), "the run made no checkpoint"
  procs[1].kill()
  code, _, err = procs[0].wait(120), *procs[0].communicate()
  assert code == 1
  last = [line for line in err.splitlines() if line.startswith("error:")]
  assert len(last) == 1 and last[0].startswith("error: ProcessLost: process 0 of 2 lost the "
                                               "others"), err[-2000:]
  assert "continue with --resume" in last[0] and "Traceback" not in err
  results = _finish(_processes(["--resume", out, "--no-progress"]))
  assert [c for c, _, _ in results] == [0, 0], [e[-2000:] for _, _, e in results]
  rows = _rows(out)
  steps = [int(r["env_step"]) for r in rows]
  assert steps == sorted(steps) and len(rows) == 2 * 6000 // 200
  assert sorted({(r["seed"], r["env_step"]) for r in rows}) == sorted(
      (str(s), str(t)) for s in range(2) for t in range(200, 6001, 200))


def test_a_stopped_process_is_declared_lost_after_the_heartbeat_timeout(tmp_path):
  """A process that stops answering (SIGSTOP: alive, silent) would leave the other waiting in
  an exchange for ever; the watch thread declares it lost after the runtime's heartbeat
  timeout and ends the run with one line."""
  import signal
  from nonmono_jax.host import processes
  out = str(tmp_path / "run")
  argv = TINY_RUN + ["--method", "hiro", "--cpu-devices", "1", "--steps", "400000"]
  procs = _processes(argv + ["--out", out])
  ckpt = os.path.join(out, "checkpoints", "hiro", "400")
  deadline = time.time() + 300
  while not os.path.isdir(ckpt) and time.time() < deadline and procs[0].poll() is None:
    time.sleep(0.2)
  procs[1].send_signal(signal.SIGSTOP)
  try:
    code = procs[0].wait(processes.HEARTBEAT_S + 60)
    err = procs[0].communicate()[1]
  finally:
    procs[1].kill()
  assert code == 1
  assert "error: ProcessLost: process 0 of 2 lost process(es) 1;" in err, err[-2000:]


def test_distributed_flags_are_checked():
  from experiments import cli
  with pytest.raises(SystemExit) as e:
    cli.main("PointMaze", TINY_RUN + ["--coordinator", "localhost:1"])
  assert e.value.code == 2


@pytest.mark.parametrize("address,message", [
    ("not a host", "--coordinator must be HOST:PORT, got 'not a host'"),
    ("127.0.0.1:99999", "--coordinator's port must be in 1-65535, got '99999'"),
    ("127.0.0.1:", "--coordinator's port must be in 1-65535, got ''"),
    (":1234", "--coordinator must be HOST:PORT"),
])
def test_a_bad_coordinator_is_one_line_before_any_join(address, message, capsys):
  """Checked before ``jax.distributed.initialize``: no traceback, no wait for a timeout."""
  from experiments import cli
  with pytest.raises(SystemExit) as e:
    cli.main("PointMaze", TINY_RUN + ["--distributed", "--coordinator", address,
                                      "--num-processes", "1", "--process-id", "0"])
  assert e.value.code == 2
  assert message in capsys.readouterr().err
