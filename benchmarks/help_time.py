"""How long the command takes to answer ``--help`` (and so any bad flag), and to import its heavy
half, in fresh processes: ``python -m benchmarks.help_time [--repeats 5] [--ref REF]``.

Each measurement is a new Python process (the OS's file cache warm after the first, Python's
bytecode cache as the checkout has it): ``python -m experiments.<task> --help`` for an ant and a
point task, and ``python -c "import experiments.cli"`` (JAX, MuJoCo, the envs: what a run
loads after its flags parse). ``--ref REF`` also times a git revision (checked out into a
temporary folder), e.g. the commit before the fast help. Writes
``benchmarks/results/help_time_<platform>_<date>.json`` with the command, machine and date.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

from benchmarks import common

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASES = {"antpush --help": ["-m", "experiments.antpush", "--help"],
         "pointmaze --help": ["-m", "experiments.pointmaze", "--help"],
         "import experiments.cli": ["-c", "import experiments.cli"]}


def _time(argv: list[str], root: str, repeats: int) -> dict:
  """Wall seconds of ``python argv`` in ``root``: the first run and the median of the rest."""
  env = {**os.environ, "PYTHONPATH": root}
  times = []
  for _ in range(repeats + 1):
    t = time.perf_counter()
    r = subprocess.run([sys.executable, *argv], cwd=root, env=env, capture_output=True)
    times.append(time.perf_counter() - t)
    if r.returncode != 0:
      raise SystemExit(f"{' '.join(argv)} failed: {r.stderr.decode()[-500:]}")
  return {"first_s": round(times[0], 3), "median_s": round(statistics.median(times[1:]), 3),
          "runs_s": [round(x, 3) for x in times]}


def main(argv=None) -> None:
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--repeats", type=int, default=5)
  p.add_argument("--ref", default=None, help="a git revision to time as well (e.g. HEAD~5)")
  p.add_argument("--out-dir", default=common.RESULTS)
  args = p.parse_args(argv)
  trees = {"this checkout": ROOT}
  with tempfile.TemporaryDirectory() as tmp:
    if args.ref:
      trees[args.ref] = common.export_revision(args.ref, tmp)
    rows = {}
    for tree, root in trees.items():
      for case, case_argv in CASES.items():
        rows[f"{tree}: {case}"] = r = _time(case_argv, root, args.repeats)
        print(f"{tree}: {case}: first {r['first_s']:.2f} s, median {r['median_s']:.2f} s",
              flush=True)
  common.write_result("help_time", args.out_dir, argv, rows=rows,
                      note="fresh processes; the machine's two cores shared with two training "
                           "runs at the lowest priority")


if __name__ == "__main__":
  main()
