"""Env steps per second of AntPush, AntFall, the bare HIRO ant and brax's stock ant, per physics.

Each env is jitted and vmapped at several batch sizes; one timed call runs ``--steps`` env
steps inside ``lax.scan`` with random actions (uniform over the action range). The bare ant is
the same model, integrator (RK4, 0.02 s x 5), solver settings and contact filtering as the maze
tasks, on a flat floor with no maze: the ratio maze / bare is the cost of the maze's contacts.

    python -m benchmarks.env_throughput                 # CPU: batches 1, 16, 256
    python -m benchmarks.env_throughput                 # GPU: batches 1, 16, 256, ..., 16384
    python -m benchmarks.env_throughput --envs AntPush AntFall --physics c mjx --steps 100

``--physics``: the maze ants' (``envs.ant_maze``): ``c`` (MuJoCo C called from inside the
jitted step, ``envs.c_physics``) and/or ``mjx``; ``auto`` is each backend's default. The ratio
c / mjx at each batch is measured in the same run. brax's stock ant is always MJX.

Writes ``benchmarks/results/env_throughput_<platform>_<date>.json`` after every row (the last
write sets ``"complete": true``) and prints a table.
"""

from __future__ import annotations

import argparse
import time

import jax

import envs
from benchmarks import common
from envs import ant_maze, maze
from envs import rollout as env_rollout
from nonmono_jax.host import plan


def _brax_ant():
  from brax import envs as brax_envs

  return brax_envs.get_environment("ant", backend="mjx")


def make_env(name: str, physics: str = "auto"):
  if name == "AntFlat":
    physics = plan.run_physics("AntPush", physics)  # auto: this backend's
    return ant_maze.AntMazeEnv(maze.FLAT, ant_maze.AntConfig(physics=physics))
  if name == "brax-ant":
    return _brax_ant()
  if name.startswith("Point"):  # the pure-JAX point robot has one physics
    return envs.make(name)
  return envs.make(name, physics=plan.run_physics(name, physics))


def measure(env, batch: int, steps: int, repeats: int) -> dict:
  """Compile time and steady-state env steps/s of ``steps`` vmapped steps."""
  limit = getattr(env, "action_limit", 1.0)

  def act(carry, s, k):
    return jax.random.uniform(k, (env.action_size,), minval=-limit, maxval=limit)

  def rollout(state, key):  # every env its own keys; the scan inside the vmap
    keys = jax.random.split(key, (batch, steps))
    return jax.vmap(lambda s, k: env_rollout.unroll(env, s, act, k)[0][0])(state, keys)

  reset = jax.jit(jax.vmap(env.reset))
  run = jax.jit(rollout)
  state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
  t0 = time.perf_counter()
  state = jax.block_until_ready(run(state, jax.random.PRNGKey(1)))
  compile_s = time.perf_counter() - t0
  best = float("inf")
  for r in range(repeats):
    t0 = time.perf_counter()
    state = jax.block_until_ready(run(state, jax.random.PRNGKey(2 + r)))
    best = min(best, time.perf_counter() - t0)
  return {"batch": batch, "steps_per_s": batch * steps / best, "compile_plus_first_s": compile_s,
          "timed_steps": steps}


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--envs", nargs="+", default=["AntFlat", "AntPush", "AntFall", "brax-ant"])
  p.add_argument("--batches", nargs="+", type=int, default=None)
  p.add_argument("--steps", type=int, default=20, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=3)
  p.add_argument("--physics", nargs="+", default=["auto"], choices=("auto", "c", "mjx"))
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  on_gpu = jax.default_backend() == "gpu"
  batches = args.batches or ([1, 16, 256, 1024, 4096, 16384] if on_gpu else [1, 16, 256])
  rows = []
  for name in args.envs:
    own = ["mjx"] if name == "brax-ant" else ["jax"] if name.startswith("Point") else args.physics
    for physics in own:  # a task's own physics, or each asked for (the maze ants)
      env = make_env(name, physics)
      physics = getattr(env, "physics", physics)
      for b in batches:
        r = {"env": name, "physics": physics, **measure(env, b, args.steps, args.repeats),
             **common.memory_stats()}
        rows.append(r)
        print(f"{name:9s} {physics:3s} batch {b:6d}: {r['steps_per_s']:10.1f} steps/s "
              f"(compile+first {r['compile_plus_first_s']:.1f} s)", flush=True)
        common.write_result("env_throughput", args.out, argv, quiet=True, complete=False,
                            results=rows)
  by = {(r["env"], r["physics"], r["batch"]): r["steps_per_s"] for r in rows}
  ratios, c_over_mjx = {}, {}
  for (name, physics, b), rate in by.items():
    if name in ("AntPush", "AntFall") and ("AntFlat", physics, b) in by:
      ratios[f"{name}/AntFlat {physics}@{b}"] = rate / by[("AntFlat", physics, b)]
    if physics == "c" and (name, "mjx", b) in by:
      c_over_mjx[f"{name}@{b}"] = rate / by[(name, "mjx", b)]
  for k, v in {**ratios, **{f"c/mjx {k}": v for k, v in c_over_mjx.items()}}.items():
    print(f"{k}: {v:.2f}")
  common.write_result("env_throughput", args.out, argv, complete=True, results=rows,
                      ratios_to_bare_ant=ratios, c_over_mjx=c_over_mjx)


if __name__ == "__main__":
  main()
