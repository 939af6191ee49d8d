"""Train one method on one task, seeds vmapped, and print S_E as it goes.

    python -m experiments.train --task PointMaze --method ours --seeds 4 --steps 40000
    python -m experiments.train --task AntPush --method hiro --seeds 5     # a GPU job

Uses ``methods.make_config(method, task)`` (SPEC's numbers for the Ant tasks, a CPU scale for
the point tasks) and the task's episode length. Every ``--chunk`` env steps it prints, per
seed, the latest evaluation success rate S_E of Middle TD3 + Low TD3 (evaluated in the
training program every ``eval_every`` steps), the final distance of those evaluation episodes
and the env steps run in each mode so far; ``--json`` writes the last of them to a file.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import jax
import numpy as np

import envs
from nonmono_jax import hierarchy, methods, train


def run(task: str, method: str, seeds: int, steps: int | None = None, chunk: int = 2000,
        seed: int = 0, log=print, **overrides) -> dict:
  preset = methods.TASKS[task]
  config = methods.make_config(method, task, **overrides)
  env = envs.make(task, episode_length=preset.episode_length)
  steps = steps or preset.total_steps
  trainer = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk)
  states = trainer.init(jax.random.PRNGKey(seed))
  start = time.perf_counter()
  row = {}
  for t0 in range(0, steps, chunk):
    states, _ = trainer.chunk(states, t0)
    done = t0 + chunk
    row = {"task": task, "method": method, "env_steps": done,
           "s_e": np.asarray(states.s_e).tolist(),
           "eval_distance": np.asarray(states.eval_distance).round(2).tolist(),
           "mode_steps": dict(zip(hierarchy.MODES, np.asarray(states.mode_steps).sum(0).tolist())),
           "seconds": round(time.perf_counter() - start, 1)}
    log(f"{method} {task} step {done:>8d}  S_E {np.round(row['s_e'], 2).tolist()}  "
        f"distance {row['eval_distance']}  modes {row['mode_steps']}  {row['seconds']} s")
  return row


def main(argv=None):
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--task", default="PointMaze", choices=list(methods.TASKS))
  p.add_argument("--method", default="ours", choices=methods.METHODS)
  p.add_argument("--seeds", type=int, default=4)
  p.add_argument("--steps", type=int, default=None, help="default: the task's preset")
  p.add_argument("--chunk", type=int, default=2000, help="env steps per jitted call")
  p.add_argument("--seed", type=int, default=0)
  p.add_argument("--json", default=None, help="write the last row to this file")
  args = p.parse_args(argv)
  row = run(args.task, args.method, args.seeds, args.steps, args.chunk, args.seed,
            log=lambda s: print(s, flush=True))
  if args.json:
    with open(args.json, "w") as f:
      json.dump(row, f, indent=1)
  return 0


if __name__ == "__main__":
  sys.exit(main())
