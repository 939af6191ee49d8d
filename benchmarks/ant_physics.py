"""Does the ant cost little more than its learner? AntPush against PointPush, same learner.

The trainer of ``train_throughput`` at the paper's settings (300-300 TD3s, batch 100; warm-up
and starting mode 0, evaluation off in the timed chunks) on AntPush with ``--physics`` and on
PointPush (the same layers, seeds and devices: the point robot's physics is a few dozen
elementwise ops, so its rate is the learner's own). Every program is compiled first, then
the chunks are timed in turns (``--repeats`` rounds, best kept), so that a busy machine slows
them alike: read the ratios ant / point of one run. The rows also give

- ``compile_s``: lowering and XLA compilation of the training chunk;
- ``gflops``: the TD3 updates' matmul FLOPs per env step (``seed_scaling.td3_flops``) times
  the rate, against the roofline of a jitted 1024^3 float32 matmul measured in the same run;
- ``eval_s``: one evaluation as the paper runs it (50 episodes of 1000 steps per seed, the
  trainer's sharded ``evaluate``), for the ant rows.

    python -m benchmarks.ant_physics --cpu-devices 2                      # hiro, ours; 4, 8 seeds
    python -m benchmarks.ant_physics --cpu-devices 2 --physics mjx --methods hiro --seeds 4

Writes ``benchmarks/results/ant_physics_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import os
import time

import jax

from benchmarks import common
from benchmarks.seed_scaling import matmul_gflops, step_flops
from nonmono_jax.core import train
from nonmono_jax.host import methods, run

CHUNK = 200


def make(env_name: str, method: str, seeds: int, physics: str, chunk: int) -> dict:
  """A compiled paper-settings trainer and its state (evaluation off in the chunk)."""
  env, config = common.paper_setup(env_name, method, physics)
  trainer = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk)
  states = jax.block_until_ready(trainer.init(jax.random.PRNGKey(0)))
  t0 = time.perf_counter()
  compiled = common.compile_chunk(trainer, states)
  compile_s = time.perf_counter() - t0
  states, _ = jax.block_until_ready(compiled(states, 0))
  return {"env": env_name, "physics": getattr(env, "physics", "jax"), "method": method,
          "seeds": seeds, "trainer": trainer, "compiled": compiled, "states": states,
          "compile_s": compile_s, "wall": float("inf"), "cpu": float("inf"), "t": chunk}


def time_round(p: dict, chunk: int) -> None:
  t0, c0 = time.perf_counter(), time.process_time()
  p["states"], _ = jax.block_until_ready(p["compiled"](p["states"], p["t"]))
  p["t"] += chunk
  p["wall"] = min(p["wall"], time.perf_counter() - t0)
  p["cpu"] = min(p["cpu"], time.process_time() - c0)


def time_evaluation(p: dict) -> float:
  """Seconds of one evaluation of every seed (the paper's 50 episodes x 1000 steps each)."""
  key = jax.random.PRNGKey(1)
  jax.block_until_ready(p["trainer"].evaluate(p["states"], key))  # compiles
  t0 = time.perf_counter()
  jax.block_until_ready(p["trainer"].evaluate(p["states"], key))
  return time.perf_counter() - t0


def row(p: dict, point: dict | None, chunk: int, roofline: float) -> dict:
  rate = p["seeds"] * chunk / p["wall"]
  flops = step_flops(p["trainer"])
  out = {k: p[k] for k in ("env", "physics", "method", "seeds", "compile_s")}
  out.update(devices=jax.device_count(), env_steps_per_s=rate,
             env_steps_per_cpu_s=p["seeds"] * chunk / p["cpu"],
             mflop_per_env_step=flops / 1e6, gflops=rate * flops / 1e9,
             roofline_fraction=rate * flops / 1e9 / roofline, timed_steps=chunk)
  if point is not None:
    out["vs_point"] = rate / (point["seeds"] * chunk / point["wall"])
  if "eval_s" in p:
    out["eval_s"], out["eval_env_steps"] = p["eval_s"], p["seeds"] * 50 * 1000
  return out


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--methods", nargs="+", default=["hiro", "ours"], choices=methods.METHODS)
  p.add_argument("--seeds", nargs="+", type=int, default=[4, 8])
  p.add_argument("--physics", default="c", choices=("c", "mjx"))
  p.add_argument("--chunk", type=int, default=CHUNK, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=3)
  p.add_argument("--no-eval", action="store_true", help="do not time an evaluation")
  p.add_argument("--cpu-devices", type=int, default=1, metavar="N")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  run.use_cpu_devices(args.cpu_devices)
  roofline = matmul_gflops()
  print(f"matmul roofline (1024^3 float32, jitted): {roofline:.1f} GFLOP/s (read again after "
        f"the timing, the better kept)", flush=True)
  progs = {}
  for method in args.methods:
    for s in args.seeds:
      for env_name in ("PointPush", "AntPush"):
        progs[env_name, method, s] = prog = make(env_name, method, s, args.physics, args.chunk)
        print(f"compiled {env_name} {prog['physics']} {method} {s} seeds: "
              f"{prog['compile_s']:.1f} s", flush=True)
  for _ in range(args.repeats):
    for prog in progs.values():
      time_round(prog, args.chunk)
  # read again after the timing, the better of the two kept: a reading that lost a core to
  # another process is not the machine's roofline
  roofline = max(roofline, matmul_gflops())
  rows = []
  for (env_name, method, s), prog in progs.items():
    if env_name == "AntPush" and not args.no_eval and s == min(args.seeds):
      prog["eval_s"] = time_evaluation(prog)
    point = progs["PointPush", method, s] if env_name == "AntPush" else None
    rows.append(row(prog, point, args.chunk, roofline))
    r = rows[-1]
    print(f"{env_name:9s} {r['physics']:3s} {method:5s} seeds {s:2d} on {r['devices']} "
          f"device(s): {r['env_steps_per_s']:6.0f} env steps/s"
          + (f" ({r['vs_point']:.2f}x the point robot)" if "vs_point" in r else "")
          + f", {r['gflops']:.1f} GFLOP/s = {100 * r['roofline_fraction']:.0f}% of the roofline"
          + (f"; one evaluation {r['eval_s']:.1f} s" if "eval_s" in r else ""), flush=True)
  common.write_result("ant_physics", args.out, argv, roofline_gflops=roofline, results=rows,
                      load_average_after=os.getloadavg(), complete=True)


if __name__ == "__main__":
  main()
