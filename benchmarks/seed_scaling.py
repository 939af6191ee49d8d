"""Do vmapped seeds pay off? Aggregate training env steps/s at 1, 4, 16 ... seeds, interleaved.

The trainer of ``train_throughput`` (warm-up and starting mode 0, evaluation off), at a task's
preset or other TD3 layer sizes (``--hidden 300 300``: the paper's). All seed counts of one
(env, method, layers) are compiled first, then timed in turns (``--repeats`` rounds, best
kept), so that a busy machine slows them alike: read the ratios to 1 seed. Besides wall time
the rows give env steps per CPU-second of this process (user + system, all threads), which a
machine shared with other jobs disturbs less.

The roofline is measured in the same run: a jitted 1024^3 float32 matmul (GFLOP/s), and the
rows state the arithmetic of one env step (the TD3 updates' matmuls, counted from the layer
sizes by ``td3_flops``) and the GFLOP/s that the measured rate achieves.

    python -m benchmarks.seed_scaling                                  # point preset
    python -m benchmarks.seed_scaling --methods hiro --hidden 300 300 --seeds 1 16 --chunk 50
    python -m benchmarks.seed_scaling --cpu-devices 2 --seeds 2 16    # lanes split over 2 devices

``--cpu-devices N`` starts JAX with N CPU devices (``run.use_cpu_devices``, the experiments'
``--cpu-devices``) and splits every trainer's seeds over them, so each seed count must be a
multiple of N; compare its rows with a run of the default one device made just before or
after (the device count is fixed per process).

Writes ``benchmarks/results/seed_scaling_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import os
import time

import jax

from benchmarks import common
from benchmarks.profile_step import make_point_trainer
from nonmono_jax.core import hierarchy
from nonmono_jax.host import methods, run


def matmul_gflops(n: int = 1024, repeats: int = 10) -> float:
  """The machine's matmul roofline as XLA:CPU reaches it: a jitted n^3 float32 matmul."""
  x = jax.random.normal(jax.random.PRNGKey(0), (n, n))
  f = jax.jit(lambda a: a @ a)
  jax.block_until_ready(f(x))
  best = float("inf")
  for _ in range(repeats):
    t0 = time.perf_counter()
    jax.block_until_ready(f(x))
    best = min(best, time.perf_counter() - t0)
  return 2 * n**3 / best / 1e9


def td3_flops(obs: int, context: int, action: int, hidden, batch: int) -> float:
  """Matmul FLOPs of one TD3 update (critic step + actor step), as ``td3.make_td3`` runs it.

  A forward pass costs 2 * sum(fan_in * fan_out) per sample; a backward pass the same for
  the input gradients (none for the first layer) and the same for the weight gradients.
  Critic step: target actor, twin target critics, twin critics forward + backward. Actor
  step: actor forward, the first critic forward and its input gradients down to the actions
  (its first layer's too), actor backward. (Before ec38806 the actor's loss ran both critics,
  counted here until then: rows of results/ from before count 2 critics in the actor step.)
  """
  def layers(n_in, n_out):
    sizes = [n_in, *hidden, n_out]
    return [a * b for a, b in zip(sizes[:-1], sizes[1:])]
  actor, critic = layers(obs + context, action), layers(obs + context + action, 1)
  fwd = lambda w: 2 * sum(w)
  bwd_in = lambda w: 2 * sum(w[1:])
  critic_step = fwd(actor) + 2 * fwd(critic) + 2 * (fwd(critic) + bwd_in(critic) + fwd(critic))
  actor_step = fwd(actor) + 2 * fwd(critic) + bwd_in(actor) + fwd(actor)
  return batch * (critic_step + actor_step)


def step_flops(trainer) -> float:
  """Matmul FLOPs per env step: a Low update every step, a Middle update every c steps."""
  cfg, env = trainer.agent.config, trainer.agent.env
  k = hierarchy.GOAL_SIZE
  low = td3_flops(env.observation_size, k, env.action_size, cfg.low.hidden, cfg.low.batch_size)
  middle = td3_flops(env.observation_size, k, k, cfg.middle.hidden, cfg.middle.batch_size)
  return cfg.low_updates * low + middle / cfg.c


def measure(env_name, method, seeds, hidden, chunk, repeats, roofline) -> list[dict]:
  progs = []
  for s in seeds:
    trainer = make_point_trainer(env_name, method, s, chunk, hidden)
    states = trainer.init(jax.random.PRNGKey(0))
    t0 = time.perf_counter()
    compiled = common.compile_chunk(trainer, states)
    compile_s = time.perf_counter() - t0
    states, _ = jax.block_until_ready(compiled(states, 0))
    progs.append({"seeds": s, "compiled": compiled, "states": states, "wall": float("inf"),
                  "cpu": float("inf"), "compile_s": compile_s, "flops": step_flops(trainer)})
  for r in range(repeats):
    for p in progs:
      t0, c0 = time.perf_counter(), time.process_time()
      p["states"], _ = jax.block_until_ready(p["compiled"](p["states"], (r + 1) * chunk))
      p["wall"] = min(p["wall"], time.perf_counter() - t0)
      p["cpu"] = min(p["cpu"], time.process_time() - c0)
  one = progs[0]
  rows = []
  for p in progs:
    rate, cpu_rate = p["seeds"] * chunk / p["wall"], p["seeds"] * chunk / p["cpu"]
    rows.append({
        "env": env_name, "method": method, "hidden": list(hidden) if hidden else "preset",
        "seeds": p["seeds"], "devices": jax.device_count(), "env_steps_per_s": rate,
        "env_steps_per_cpu_s": cpu_rate,
        "vs_first": rate / (one["seeds"] * chunk / one["wall"]),
        "cpu_vs_first": cpu_rate / (one["seeds"] * chunk / one["cpu"]),
        "mflop_per_env_step": p["flops"] / 1e6, "gflops": rate * p["flops"] / 1e9,
        "gflops_per_cpu_s": cpu_rate * p["flops"] / 1e9, "roofline_gflops": roofline,
        "compile_s": p["compile_s"], "timed_steps": chunk, "repeats": repeats,
        "load_average_after": os.getloadavg()})
  return rows


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--envs", nargs="+", default=["PointPush"])
  p.add_argument("--methods", nargs="+", default=["ours", "hiro"], choices=methods.METHODS)
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 4, 16])
  p.add_argument("--hidden", nargs="+", type=int, default=None,
                 help="Low and Middle TD3 layers (default: the task's preset)")
  p.add_argument("--chunk", type=int, default=500, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=3)
  p.add_argument("--cpu-devices", type=int, default=1, metavar="N",
                 help="split the seeds over N CPU devices (each --seeds a multiple of N)")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  run.use_cpu_devices(args.cpu_devices)
  roofline = matmul_gflops()
  print(f"matmul roofline (1024^3 float32, jitted): {roofline:.1f} GFLOP/s", flush=True)
  rows = []
  for name in args.envs:
    for method in args.methods:
      rows += measure(name, method, args.seeds, args.hidden, args.chunk, args.repeats,
                      roofline)
      for r in rows[-len(args.seeds):]:
        print(f"{name:9s} {method:5s} {str(r['hidden']):10s} seeds {r['seeds']:3d} on "
              f"{r['devices']} device(s): "
              f"{r['env_steps_per_s']:7.0f} env steps/s ({r['vs_first']:.2f}x), "
              f"{r['env_steps_per_cpu_s']:7.0f} per CPU-s ({r['cpu_vs_first']:.2f}x), "
              f"{r['gflops']:.1f} GFLOP/s of {roofline:.0f}", flush=True)
      common.write_result("seed_scaling", args.out, argv, quiet=True, complete=False,
                          roofline_gflops=roofline, results=rows)
  common.write_result("seed_scaling", args.out, argv, complete=True, roofline_gflops=roofline,
                      results=rows)


if __name__ == "__main__":
  main()
