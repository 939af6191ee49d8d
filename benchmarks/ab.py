"""Two revisions of one benchmark, interleaved in fresh processes: the speed ratio a shared
machine can give.

    python -m benchmarks.ab --ref HEAD --rounds 3 -- train_throughput --envs AntPush \\
        --methods ours --seeds 1 --no-eval

runs ``python -m benchmarks.<name> <args>`` alternately on this checkout's code (its working
tree, uncommitted changes included) and on ``--ref``'s (exported into a temporary folder, with
this checkout's ``benchmarks/`` copied over it: one measurement, two versions of the code it
measures), each round in the other order, and reads ``--metric`` (default
``env_steps_per_s``) from every row of each result file. Another process on the machine
slows both sides of a round alike, and its drift over minutes cancels between the orders, so
read the ratio per round (this / ref) and their median, not the absolute rates; at a heavy
load read ``env_steps_per_cpu_s`` (``train_throughput``), which preemption does not stretch.
Writes ``benchmarks/results/ab_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile

from benchmarks import common


def _run(root: str, name: str, args: list[str], out: str, metric: str) -> list[float]:
  """``metric`` of every row of one fresh run of benchmark ``name`` in ``root``."""
  return [row[metric] for row in common.rows(common.run_fresh(root, name, args, out))]


def main(argv=None) -> None:
  argv = sys.argv[1:] if argv is None else argv
  cut = argv.index("--") if "--" in argv else len(argv)
  ours, theirs = argv[:cut], argv[cut + 1:]
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--ref", required=True, help="the git revision to compare with (e.g. HEAD)")
  p.add_argument("--rounds", type=int, default=3)
  p.add_argument("--metric", default="env_steps_per_s")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(ours)
  if not theirs:
    p.error("give the benchmark after --, e.g. -- train_throughput --seeds 1")
  name, bench_args = theirs[0], theirs[1:]
  rounds = []
  with tempfile.TemporaryDirectory() as tmp:
    ref = common.export_revision(args.ref, os.path.join(tmp, "ref"))
    shutil.rmtree(os.path.join(ref, "benchmarks"))
    shutil.copytree(os.path.join(common.ROOT, "benchmarks"), os.path.join(ref, "benchmarks"),
                    ignore=shutil.ignore_patterns("results", "__pycache__"))
    trees = {"this": common.ROOT, "ref": ref}
    for i in range(args.rounds):
      order = ["ref", "this"] if i % 2 == 0 else ["this", "ref"]
      got = {}
      for side in order:
        out = os.path.join(tmp, f"{side}{i}")
        got[side] = _run(trees[side], name, bench_args, out, args.metric)
      ratios = [a / b for a, b in zip(got["this"], got["ref"])]
      rounds.append({"order": order, **got, "ratio": ratios})
      print(f"round {i + 1}: this {got['this']} ref {got['ref']} ratio "
            f"{[round(x, 3) for x in ratios]}", flush=True)
  median = [statistics.median(r["ratio"][j] for r in rounds)
            for j in range(len(rounds[0]["ratio"]))]
  print("median ratio (this / ref) per row:", [round(x, 3) for x in median])
  common.write_result("ab", args.out, argv, ref=args.ref, benchmark=name, metric=args.metric,
                      rounds=rounds, median_ratio=median,
                      note="fresh processes, interleaved; the order alternates per round")


if __name__ == "__main__":
  main()
