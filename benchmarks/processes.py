"""Does a run over several processes cost anything? 2 processes x 1 CPU device against 1
process x 2 CPU devices, the same lanes per device.

The trainer of ``seed_scaling`` at the point preset (``--seeds`` lanes, warm-up and starting
mode 0, evaluation off), one chunk compiled and then timed ``--chunks`` times; the two layouts
run one after the other in ``--rounds`` alternating rounds (best chunk kept per layout), so a
busy machine slows them alike. In the multi-process layout the processes join JAX's runtime
on localhost (``nonmono_jax.host.processes``), each pinned to its share of the cores before JAX
loads (``experiments/cores.py``, as the experiment command does), and, as a run does between
chunks, all-gather the chunk's metrics; the rate is process 0's.

    python -m benchmarks.processes --seeds 16 --rounds 3

Writes ``benchmarks/results/processes_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def worker(args) -> None:
  """One process of a layout: its env steps/s (process 0 prints them as JSON)."""
  from experiments import cores
  if args.num_processes > 1:  # as the experiment command does, before JAX loads
    cores.share(["--distributed", "--coordinator", f"localhost:{args.port}", "--num-processes",
                 str(args.num_processes), "--process-id", str(args.process_id)])
  import jax

  from benchmarks import common
  from nonmono_jax.host import processes, run
  run.use_cpu_devices(args.cpu_devices)
  if args.num_processes > 1:
    processes.join(f"localhost:{args.port}", args.num_processes, args.process_id)
  from benchmarks.profile_step import make_point_trainer
  trainer = make_point_trainer("PointPush", args.method, args.seeds, args.chunk)
  states = trainer.init(jax.random.PRNGKey(0))
  compiled = common.compile_chunk(trainer, states)
  states, m = compiled(states, 0)
  processes.gather(m)
  best = float("inf")
  for i in range(args.chunks):
    t0 = time.perf_counter()
    states, m = compiled(states, (i + 1) * args.chunk)
    processes.gather(m)  # what a run does between chunks (and it waits for the chunk)
    best = min(best, time.perf_counter() - t0)
  if processes.writer():
    print(json.dumps({"env_steps_per_s": args.seeds * args.chunk / best,
                      "processes": jax.process_count(), "devices": jax.device_count()}))
  processes.leave(0)


def _layout(args, n_proc: int, devices: int) -> float:
  """Runs one layout; process 0's rate."""
  with socket.socket() as s:
    s.bind(("localhost", 0))
    port = s.getsockname()[1]
  cmd = [sys.executable, "-m", "benchmarks.processes", "--worker", "--seeds", str(args.seeds),
         "--chunk", str(args.chunk), "--chunks", str(args.chunks), "--method", args.method,
         "--cpu-devices", str(devices), "--num-processes", str(n_proc), "--port", str(port)]
  procs = [subprocess.Popen(cmd + ["--process-id", str(i)], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True) for i in range(n_proc)]
  outs = [p.communicate()[0] for p in procs]
  line = [l for l in outs[0].splitlines() if l.startswith("{")]
  if not line or any(p.returncode for p in procs):
    raise RuntimeError(f"layout {n_proc} x {devices} failed: {outs}")
  return json.loads(line[-1])["env_steps_per_s"]


def main(argv=None):
  p = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
  p.add_argument("--seeds", type=int, default=16)
  p.add_argument("--method", default="hiro")
  p.add_argument("--chunk", type=int, default=400, help="env steps per timed call")
  p.add_argument("--chunks", type=int, default=3, help="timed chunks per process")
  p.add_argument("--rounds", type=int, default=3)
  p.add_argument("--out", default=None)
  p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
  p.add_argument("--cpu-devices", type=int, default=1, help=argparse.SUPPRESS)
  p.add_argument("--num-processes", type=int, default=1, help=argparse.SUPPRESS)
  p.add_argument("--process-id", type=int, default=0, help=argparse.SUPPRESS)
  p.add_argument("--port", type=int, default=0, help=argparse.SUPPRESS)
  args = p.parse_args(argv)
  if args.worker:
    return worker(args)
  from benchmarks import common
  rates = {"1 process x 2 devices": [], "2 processes x 1 device": []}
  for r in range(args.rounds):
    rates["1 process x 2 devices"].append(_layout(args, 1, 2))
    rates["2 processes x 1 device"].append(_layout(args, 2, 1))
    print(f"round {r}: " + ", ".join(f"{k} {v[-1]:.0f}" for k, v in rates.items()), flush=True)
  best = {k: max(v) for k, v in rates.items()}
  ratio = best["2 processes x 1 device"] / best["1 process x 2 devices"]
  print(f"best: {best}; 2 processes / 1 process: {ratio:.2f}x")
  common.write_result("processes", args.out or common.RESULTS, argv, rounds=rates, best=best,
                      ratio=ratio, seeds=args.seeds, method=args.method, chunk=args.chunk,
                      load_average_after=os.getloadavg())


if __name__ == "__main__":
  main()
