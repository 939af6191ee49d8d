"""Training env steps per second of the vmapped trainer, at the paper's settings.

The paper's settings: one env per seed, one Low TD3 update per env step (batch 100, 300-300
networks), a Middle TD3 update with relabelling every c = 10 steps; for ours also the Middle PPO
every 30 steps, the Top PPO every 400 and the mode switch; evaluation (50 episodes every 10K
steps) is off here (``eval_every`` beyond the timed steps) and timed on its own in ``eval_s``.
Warm-up and the starting mode are set to 0 so that every timed step trains with all three
modes live. Seeds are vmapped; one timed call is a jitted chunk of ``--chunk`` steps.

    python -m benchmarks.train_throughput                     # ours and HIRO, PointPush, AntPush
    python -m benchmarks.train_throughput --envs PointPush --methods ours --seeds 1 4 16
    python -m benchmarks.train_throughput --num-envs 16        # envs per seed (GPU filling)

Writes ``benchmarks/results/train_throughput_<platform>_<date>.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import jax

import envs
from benchmarks import common
from nonmono_jax import methods, train


def measure(env_name: str, method: str, seeds: int, num_envs: int, chunk: int,
            repeats: int, time_eval: bool) -> dict:
  env = envs.make(env_name, episode_length=1000)
  base = methods.make_config(method, env_name.replace("Point", "Ant"))  # the paper's settings
  config = dataclasses.replace(base, warmup_steps=0, num_envs=num_envs, eval_every=10**9,
                               top=dataclasses.replace(base.top, starting_steps=0))
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
  eval_s = None
  if time_eval:
    evaluate = jax.jit(jax.vmap(trainer.agent.evaluate, in_axes=(0, 0, None)))
    key = jax.random.PRNGKey(1)
    jax.block_until_ready(evaluate(states.low.params, states.middle.params, key))
    t0 = time.perf_counter()
    jax.block_until_ready(evaluate(states.low.params, states.middle.params, key))
    eval_s = time.perf_counter() - t0
  return {"env": env_name, "method": method, "seeds": seeds, "envs_per_seed": num_envs,
          "env_steps_per_s": seeds * num_envs * chunk / best, "compile_plus_first_s": compile_s,
          "timed_steps_per_seed": chunk * num_envs,
          "eval_s": eval_s, "eval_env_steps": seeds * config.eval_episodes * 1000}


def main(argv=None):
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--envs", nargs="+", default=["PointPush", "AntPush"])
  p.add_argument("--methods", nargs="+", default=["ours", "hiro"], choices=methods.METHODS)
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 4, 16])
  p.add_argument("--num-envs", nargs="+", type=int, default=[1], help="envs per seed")
  p.add_argument("--chunk", type=int, default=200, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=2)
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  rows = []
  for name in args.envs:
    for method in args.methods:
      for e in args.num_envs:
        for s in args.seeds:
          # One evaluation is 50 episodes x 1000 steps per seed: minutes of MJX on a CPU.
          time_eval = name.startswith("Point") or jax.default_backend() != "cpu"
          r = measure(name, method, s, e, args.chunk, args.repeats, time_eval)
          rows.append(r)
          print(f"{name:9s} {method:5s} seeds {s:3d} x envs {e:3d}: "
                f"{r['env_steps_per_s']:8.1f} env steps/s (compile+first "
                f"{r['compile_plus_first_s']:.1f} s; one evaluation {r['eval_s']} s)",
                flush=True)
  common.write_result(
      "train_throughput", args.out, argv,
      settings="paper: Low TD3 update every vector step (batch 100, 300-300), Middle TD3 + "
               "relabelling every 10 steps; ours: + Middle PPO every 30, Top PPO every 400, "
               "Top mode every 50; warm-up and starting mode 0; evaluation timed apart",
      results=rows)


if __name__ == "__main__":
  main()
