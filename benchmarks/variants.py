"""Variants as lanes: wall time, compile included, of one program against one run per variant.

Two scenarios on PointPush at the point preset, every step live (``common.ALL_MODES_LIVE``:
no warm-up, no starting mode, no evaluation): ours and its three ablations, and a 3 x 3 grid
of top.alpha x top.s_o for ours. Each is timed as one program (``train.make_group_trainer``:
variants x seeds lanes) and as one trainer per variant run one after another
(``train.make_trainer``, as before variants existed), from building the trainer to the
last chunk's result. No persistent compilation cache is set, so each program compiles.

    python -m benchmarks.variants                         # 8 seeds, 2000 steps
    python -m benchmarks.variants --seeds 2 --steps 400 --chunk 200 --scenarios ablations

Writes ``benchmarks/results/variants_<platform>_<date>.json`` (with the load average before
and after each measurement: the machine may be shared).
"""

from __future__ import annotations

import argparse
import os
import time

import jax

import envs
from benchmarks import common
from nonmono_jax.core import train
from nonmono_jax.host import plan as plan_lib

SCENARIOS = {
    "ablations": (["ours", "ours-no-reward-mod", "ours-no-loss-mod", "ours-no-mods"], {}),
    "alpha_x_s_o": (["ours"], {"top.alpha": [(0, 0.4, 0.7), (0, 0.2, 0.35), (0, 0.8, 1.4)],
                               "top.s_o": [(0.6, 0.6, 0.6), (0.4, 0.4, 0.4), (0.8, 0.8, 0.8)]}),
}


def _timed(make, steps: int, chunk: int) -> float:
  """Seconds from building a trainer to its last chunk's result (compile included)."""
  start = time.perf_counter()
  trainer = make()
  states = trainer.init(jax.random.PRNGKey(0))
  for t0 in range(0, steps, chunk):
    states, metrics = trainer.chunk(states, t0)
  jax.block_until_ready(metrics)
  return time.perf_counter() - start


def measure(scenario: str, seeds: int, steps: int, chunk: int) -> dict:
  method_names, sweep = SCENARIOS[scenario]
  plan = plan_lib.new_run("PointPush", method_names, preset="quick", out=os.devnull,
                          overrides=common.ALL_MODES_LIVE, sweep=sweep,
                          run={"seeds": seeds, "steps": steps, "chunk": chunk})
  env = envs.make("PointPush", episode_length=plan.spec.episode_length)
  configs = list(plan.configs.values())
  load = [os.getloadavg()[0]]
  grouped = _timed(lambda: train.make_group_trainer(env, configs, seeds, chunk), steps, chunk)
  load.append(os.getloadavg()[0])
  alone = {name: _timed(lambda c=c: train.make_trainer(env, c, seeds, chunk), steps, chunk)
           for name, c in plan.configs.items()}
  load.append(os.getloadavg()[0])
  separate = sum(alone.values())
  row = {"scenario": scenario, "variants": list(plan.configs), "seeds": seeds, "steps": steps,
         "chunk": chunk, "one_program_s": grouped, "separate_runs_s": separate,
         "separate_run_s": alone, "speedup": separate / grouped,
         "load_average_1min": {"before": load[0], "between": load[1], "after": load[2]}}
  print(f"{scenario}: {len(configs)} variants x {seeds} seeds x {steps} steps: one program "
        f"{grouped:.0f} s, {len(configs)} runs {separate:.0f} s ({separate / grouped:.1f}x)",
        flush=True)
  return row


def main(argv=None):
  p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
  p.add_argument("--seeds", type=int, default=8)
  p.add_argument("--steps", type=int, default=2000)
  p.add_argument("--chunk", type=int, default=1000)
  p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
  p.add_argument("--note", default="", help="recorded with the result (e.g. the machine's load)")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  rows = []
  for scenario in args.scenarios:
    rows.append(measure(scenario, args.seeds, args.steps, args.chunk))
    common.write_result("variants", args.out, argv, quiet=True, note=args.note, rows=rows,
                        complete=False)
  common.write_result("variants", args.out, argv, note=args.note, rows=rows, complete=True)


if __name__ == "__main__":
  main()
