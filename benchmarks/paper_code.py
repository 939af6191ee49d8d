"""The paper's code and ours side by side on one machine: training env steps per second and
per CPU-second, each in fresh processes, interleaved.

    python -m benchmarks.paper_code --rounds 2
    python -m benchmarks.paper_code --rounds 2 -- ant_physics --cpu-devices 2 --methods ours \\
        --seeds 4 --repeats 2 --no-eval

Each round runs both sides, in the other order in the next round:

- the paper's code through the harness (``reference.run``: AntPush, its loop and its settings,
  learning from env step ``--warmup`` on, its evaluations and checkpoints beyond the run, torch
  on ``--threads`` threads, MuJoCo 2.0.0's contacts as the study runs it), ``--steps``
  learning steps; its rate is the median over the windows of ``--window`` steps after the
  warm-up (``windows.csv``: ``train_steps_per_s`` and ``train_steps_per_cpu_s``);
- ours: the benchmark after ``--`` (default ``train_throughput`` at the paper's settings, 1 seed,
  1 device, all modes live, evaluation off), every row of its result.

It needs the reference venv and the fetched code (``python -m reference.setup``). Another
process on the machine slows both sides of a round alike: read the ratios (ours / the code) per
round and their median; at a heavy load read the CPU-second ones, which preemption does not
stretch (a thread pool's spinning counts, on both sides). Per process, the comparison that
counts is the wall ratio on an idle machine.

Writes ``benchmarks/results/paper_code_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

from benchmarks import common

OURS = ["train_throughput", "--envs", "AntPush", "--methods", "ours", "--seeds", "1",
        "--no-eval", "--repeats", "3"]
METRICS = ("env_steps_per_s", "env_steps_per_cpu_s")


def run_code(out: str, steps: int, warmup: int, window: int, threads: int) -> dict:
  """The paper's code's training rates (medians over its windows after the warm-up)."""
  cmd = [sys.executable, "-m", "reference.run", "--out", out, "--seed", "0",
         "--steps", str(warmup + steps + window), "--start-timestep", str(warmup),
         "--evaluation-interval", str(10**9), "--checkpoint-every", str(10**9),
         "--window", str(window), "--threads", str(threads), "--physics", "mujoco200",
         "--eval", "batched-td3"]
  r = subprocess.run(cmd, cwd=common.ROOT, capture_output=True, text=True,
                     env={**os.environ, "PYTHONPATH": common.ROOT})
  if r.returncode != 0:
    raise SystemExit(f"reference.run failed:\n{r.stdout[-1500:]}{r.stderr[-1500:]}")
  with open(os.path.join(out, "windows.csv"), newline="") as f:
    learning = [w for w in csv.DictReader(f) if int(w["step"]) > 0]
  return {"env_steps_per_s": statistics.median(float(w["train_steps_per_s"]) for w in learning),
          "env_steps_per_cpu_s": statistics.median(float(w["train_steps_per_cpu_s"])
                                                   for w in learning),
          "windows": len(learning), "threads": threads}


def one_round(i: int, args, ours: list[str], tmp: str) -> dict:
  got = {}
  order = ["code", "ours"] if i % 2 == 0 else ["ours", "code"]
  for side in order:
    out = os.path.join(tmp, f"{side}{i}")
    if side == "code":
      got["code"] = run_code(out, args.steps, args.warmup, args.window, args.threads)
    else:
      got["ours"] = [{k: row[k] for k in (*METRICS, "env", "method", "seeds", "devices")
                      if k in row}
                     for row in common.rows(common.run_fresh(common.ROOT, ours[0], ours[1:],
                                                             out))]
  got["ratio"] = [{m: row[m] / got["code"][m] for m in METRICS} for row in got["ours"]]
  return {"order": order, **got}


def main(argv=None) -> None:
  argv = sys.argv[1:] if argv is None else argv
  cut = argv.index("--") if "--" in argv else len(argv)
  mine, ours = argv[:cut], argv[cut + 1:] or OURS
  p = argparse.ArgumentParser(
      prog="python -m benchmarks.paper_code",
      usage="%(prog)s [options] [-- BENCHMARK ARGS (ours' side; default: "
            + " ".join(OURS) + ")]", description=common.description(__doc__))
  p.add_argument("--rounds", type=int, default=2)
  p.add_argument("--steps", type=int, default=4000, help="the code's learning steps")
  p.add_argument("--warmup", type=int, default=1000, help="the code's warm-up (start_timestep)")
  p.add_argument("--window", type=int, default=1000, help="env steps per timed window")
  p.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                 help="torch threads (default: the machine's cores, as ours uses them)")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(mine)
  if args.steps < args.window or args.steps % args.window or args.warmup % args.window:
    p.error("--steps and --warmup must be multiples of --window (and --steps >= --window)")
  rounds = []
  with tempfile.TemporaryDirectory() as tmp:
    for i in range(args.rounds):
      rounds.append(one_round(i, args, ours, tmp))
      r = rounds[-1]
      print(f"round {i + 1}: the code {r['code']['env_steps_per_s']:.0f} env steps/s "
            f"({r['code']['env_steps_per_cpu_s']:.0f} per CPU-s); ours "
            + ", ".join(f"{row['env_steps_per_s']:.0f} ({row['env_steps_per_cpu_s']:.0f})"
                        for row in r["ours"])
            + "; ratio " + ", ".join(
                f"{x['env_steps_per_s']:.2f}x ({x['env_steps_per_cpu_s']:.2f}x)"
                for x in r["ratio"]), flush=True)
      common.write_result("paper_code", args.out, argv, quiet=True, complete=False,
                          ours_command=" ".join(ours), rounds=rounds)
  median = [{m: statistics.median(r["ratio"][j][m] for r in rounds) for m in METRICS}
            for j in range(len(rounds[0]["ratio"]))]
  print("median ratio (ours / the code) per row of ours:", median)
  common.write_result("paper_code", args.out, argv, complete=True, ours_command=" ".join(ours),
                      rounds=rounds, median_ratio=median,
                      note="fresh processes, interleaved; the order alternates per round; "
                           "the code's rate is the median of its windows after the warm-up")


if __name__ == "__main__":
  main()
