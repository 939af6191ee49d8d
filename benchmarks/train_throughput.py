"""Training env steps per second of the vmapped trainer, at the paper's settings.

One env per seed, one Low TD3 update per env step (batch 100, 300-300 networks), a Middle TD3
update with relabelling every c = 10 steps; warm-up is set to 0 so that every timed step
trains. Seeds are vmapped; one timed call is a jitted chunk of ``--chunk`` steps.

    python -m benchmarks.train_throughput                     # PointPush and AntPush, 1/4/16 seeds
    python -m benchmarks.train_throughput --envs PointPush --seeds 1 4 16

Methods: HIRO so far (the agent step of the paper's method is still being built).
Writes ``benchmarks/results/train_throughput_<platform>_<date>.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import time

import jax

import envs
from benchmarks import common
from nonmono_jax import agent as agent_lib
from nonmono_jax import train


def measure(env_name: str, seeds: int, chunk: int, repeats: int) -> dict:
  env = envs.make(env_name, episode_length=1000)
  config = agent_lib.AgentConfig(warmup_steps=0)
  trainer = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk)
  t0 = time.perf_counter()
  states = jax.block_until_ready(trainer.init(jax.random.PRNGKey(0)))
  states, _ = jax.block_until_ready(trainer.chunk(states, 0))
  compile_s = time.perf_counter() - t0
  best = float("inf")
  for r in range(repeats):
    t0 = time.perf_counter()
    states, _ = jax.block_until_ready(trainer.chunk(states, (r + 1) * chunk))
    best = min(best, time.perf_counter() - t0)
  return {"env": env_name, "method": "hiro", "seeds": seeds, "envs_per_seed": 1,
          "env_steps_per_s": seeds * chunk / best, "compile_plus_first_s": compile_s,
          "timed_steps_per_seed": chunk}


def main(argv=None):
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--envs", nargs="+", default=["PointPush", "AntPush"])
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 4, 16])
  p.add_argument("--chunk", type=int, default=200, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=2)
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  rows = []
  for name in args.envs:
    for s in args.seeds:
      r = measure(name, s, args.chunk, args.repeats)
      rows.append(r)
      print(f"{name:9s} hiro seeds {s:3d}: {r['env_steps_per_s']:8.1f} env steps/s "
            f"(compile+first {r['compile_plus_first_s']:.1f} s)", flush=True)
  common.write_result(
      "train_throughput", args.out, argv,
      settings="paper: 1 env/seed, Low TD3 update every step (batch 100, 300-300), "
               "Middle TD3 + relabelling every 10 steps, warm-up 0",
      results=rows)


if __name__ == "__main__":
  main()
