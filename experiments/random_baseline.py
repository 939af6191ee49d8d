"""The random-policy baseline of a maze task: how far uniform random actions get.

    python -m experiments.random_baseline                      # PointPush, 256 episodes
    python -m experiments.random_baseline --env AntPush --episodes 16 --episode-length 100

Runs ``--episodes`` episodes at once (``vmap``) for ``--episode-length`` steps inside one jitted
``lax.scan`` and prints the success rate (within the task's success radius at any step, as in
the paper's evaluation), the final and the closest distance to the target, and the env
steps per second. The numbers are the floor that a learning agent must clearly beat.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import jax

import envs
from envs import rollout


def run(name: str, episodes: int, episode_length: int, seed: int = 0) -> dict:
  env = envs.make(name, episode_length=episode_length)
  lim = env.action_limit

  def act(carry, s, k):
    return jax.random.uniform(k, (env.action_size,), minval=-lim, maxval=lim)

  def observe(carry, s, s_next, k):
    return carry, (s_next.success, s_next.distance)

  def episode(key):
    k0, k1 = jax.random.split(key)
    _, (success, distance) = rollout.unroll(env, env.reset(k0), act,
                                            jax.random.split(k1, episode_length),
                                            observe=observe)
    return success.max(), distance[-1], distance.min()

  fn = jax.jit(jax.vmap(episode))
  keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
  t0 = time.perf_counter()
  jax.block_until_ready(fn(keys))
  compile_s = time.perf_counter() - t0
  t0 = time.perf_counter()
  success, final, closest = jax.block_until_ready(fn(jax.random.split(jax.random.PRNGKey(seed + 1),
                                                                       episodes)))
  run_s = time.perf_counter() - t0
  return {
      "env": name, "episodes": episodes, "episode_length": episode_length,
      "success_rate": float(success.mean()),
      "final_distance": float(final.mean()), "closest_distance": float(closest.mean()),
      "target": [float(x) for x in env.target], "success_radius": env.success_radius,
      "env_steps_per_s": episodes * episode_length / run_s, "compile_s": compile_s,
  }


def main(argv=None):
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("--env", default="PointPush", choices=envs.NAMES)
  p.add_argument("--episodes", type=int, default=256)
  p.add_argument("--episode-length", type=int, default=500)
  p.add_argument("--seed", type=int, default=0)
  p.add_argument("--json", action="store_true", help="print one JSON line instead of text")
  args = p.parse_args(argv)
  if args.episodes <= 0 or args.episode_length <= 0:
    p.error("--episodes and --episode-length must be positive")
  r = run(args.env, args.episodes, args.episode_length, args.seed)
  if args.json:
    print(json.dumps(r))
    return
  print(f"{r['env']}: random policy, {r['episodes']} episodes of {r['episode_length']} steps")
  print(f"  target {r['target']}, success radius {r['success_radius']}")
  print(f"  success rate     {r['success_rate']:.3f}")
  print(f"  final distance   {r['final_distance']:.2f}")
  print(f"  closest distance {r['closest_distance']:.2f}")
  print(f"  {r['env_steps_per_s']:.0f} env steps/s (compile {r['compile_s']:.1f} s)")


if __name__ == "__main__":
  sys.exit(main())
