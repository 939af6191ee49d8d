"""Training env steps per second of the vmapped trainer, at the paper's settings.

The paper's settings: one env per seed, one Low TD3 update per env step (batch 100, 300-300
networks), a Middle TD3 update with relabelling every c = 10 steps; for ours also the Middle PPO
every 30 steps, the Top PPO every 400 and the mode switch; evaluation (50 episodes every 10K
steps) is off here (``eval_every`` beyond the timed steps) and timed on its own in ``eval_s``
(the trainer's ``evaluate``: the paper's 50 episodes of 1000 steps per seed, seeds split over
the devices as in training; not for the ant on MJX on a CPU, where it takes minutes).
Warm-up and the starting mode are set to 0 so that every timed step trains with all three
modes live. Seeds are vmapped; one timed call is a jitted chunk of ``--chunk`` steps.

    python -m benchmarks.train_throughput                     # ours and HIRO, PointPush, AntPush
    python -m benchmarks.train_throughput --envs PointPush --methods ours --seeds 1 4 16
    python -m benchmarks.train_throughput --num-envs 16        # envs per seed (GPU filling)
    python -m benchmarks.train_throughput --envs AntPush --seeds 1 5 16 --num-envs 1 16 64 256
    python -m benchmarks.train_throughput --cpu-devices 2 --seeds 4 16   # seeds over 2 CPU devices
    python -m benchmarks.train_throughput --envs AntPush --physics mjx   # the ant on MJX

With E envs per seed the updates are the paper's per vector step (``num_envs`` alone: one
Low update per vector step), unless ``--grad-steps U`` is given: then U updates per vector
step of batch 100 E / U (``methods.widen_layer``'s data use per env step); ``--paper-updates`` is
U = E, the paper's updates per env step exactly (E updates of batch 100 per vector step).

``compile_s`` is the chunk's lowering and XLA compilation alone; ``memory`` is XLA's
accounting of the chunk program (arguments + outputs + temporaries - donated), and on a GPU
``peak_bytes_in_use`` the process's allocator peak so far. ``env_steps_per_cpu_s`` divides by
the process's CPU time (all its threads) instead of the wall clock: on a machine shared with
other work it is not stretched by their preemption, so it compares two programs where the wall
rate cannot (``benchmarks.ab --metric env_steps_per_cpu_s``); it does count a thread pool's
spinning, and on an idle machine two busy threads make it half the wall rate.

Writes ``benchmarks/results/train_throughput_<platform>_<date>.json`` after every row (the
last write sets ``"complete": true``) and prints a table.
"""

from __future__ import annotations

import argparse
import time

import jax

from benchmarks import common
from benchmarks.common import ALL_MODES_LIVE
from nonmono_jax.core import train
from nonmono_jax.core.config import override
from nonmono_jax.host import methods, run


def measure(env_name: str, method: str, seeds: int, num_envs: int, chunk: int,
            repeats: int, time_eval: bool, grad_steps: int | None = None,
            physics: str = "auto") -> dict:
  env = common.paper_env(env_name, physics)
  task = common.paper_task(env_name)  # not paper_setup: widen_layer reads the config first
  base = common.paper_config(method, task)
  if grad_steps is not None:  # widened, its buffers sized for a run of one chunk
    spec = methods.RunSpec(steps=chunk, seeds=seeds, episode_length=1000, chunk=chunk,
                           checkpoint_every=chunk)
    layer, spec = methods.widen_layer(base, spec, num_envs, grad_steps)
    base = common.paper_config(method, task, {**layer, **methods.buffer_sizes(
        spec.steps, base.c, num_envs)})
  config = override(base, {**ALL_MODES_LIVE, "num_envs": num_envs})
  trainer = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk)
  states = jax.block_until_ready(trainer.init(jax.random.PRNGKey(0)))
  t0 = time.perf_counter()
  compiled = common.compile_chunk(trainer, states)
  compile_s = time.perf_counter() - t0
  memory = train.compiled_bytes(compiled)
  t0 = time.perf_counter()
  states, _ = jax.block_until_ready(compiled(states, 0))
  first_s = time.perf_counter() - t0
  best, best_cpu = float("inf"), float("inf")
  for r in range(repeats):
    t0, c0 = time.perf_counter(), time.process_time()
    states, _ = jax.block_until_ready(compiled(states, (r + 1) * chunk))
    best = min(best, time.perf_counter() - t0)
    best_cpu = min(best_cpu, time.process_time() - c0)
  eval_s = None
  if time_eval:  # the trainer's own: the seeds split over the devices as in training
    key = jax.random.PRNGKey(1)
    jax.block_until_ready(trainer.evaluate(states, key))
    t0 = time.perf_counter()
    jax.block_until_ready(trainer.evaluate(states, key))
    eval_s = time.perf_counter() - t0
  return {"env": env_name, "physics": getattr(env, "physics", "jax"), "method": method,
          "seeds": seeds, "devices": jax.device_count(),
          "envs_per_seed": num_envs,
          "low_updates": config.low_updates, "low_batch": config.low.batch_size,
          "env_steps_per_s": seeds * num_envs * chunk / best,
          "env_steps_per_cpu_s": seeds * num_envs * chunk / best_cpu, "compile_s": compile_s,
          "first_chunk_s": first_s, "timed_steps_per_seed": chunk * num_envs,
          "memory": memory, **common.memory_stats(),
          "eval_s": eval_s, "eval_env_steps": seeds * config.eval_episodes * 1000}


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--envs", nargs="+", default=["PointPush", "AntPush"])
  p.add_argument("--methods", nargs="+", default=["ours", "hiro"], choices=methods.METHODS)
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 4, 16])
  p.add_argument("--num-envs", nargs="+", type=int, default=[1], help="envs per seed")
  p.add_argument("--grad-steps", type=int, default=None,
                 help="TD3 updates per vector step, of batch 100 E / U (methods.widen_layer); "
                      "default: one update of batch 100 per vector step")
  p.add_argument("--paper-updates", action="store_true",
                 help="U = E for every E: the paper's TD3 updates per env step exactly")
  p.add_argument("--chunk", type=int, default=200, help="env steps per timed call")
  p.add_argument("--repeats", type=int, default=2)
  p.add_argument("--cpu-devices", type=int, default=1, metavar="N",
                 help="split the seeds over N CPU devices (each --seeds a multiple of N)")
  p.add_argument("--physics", default="auto", choices=("auto", "c", "mjx"),
                 help="the ant's physics (auto: c on a CPU, mjx on an accelerator)")
  p.add_argument("--no-eval", action="store_true", help="do not time an evaluation")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  run.use_cpu_devices(args.cpu_devices)
  settings = ("paper: Low TD3 update every vector step (batch 100, 300-300), Middle TD3 + "
              "relabelling every 10 steps; ours: + Middle PPO every 30, Top PPO every 400, "
              "Top mode every 50; warm-up and starting mode 0; evaluation timed apart")
  if args.grad_steps is not None and args.paper_updates:
    p.error("--grad-steps and --paper-updates exclude each other")
  if args.grad_steps is not None:
    settings += f"; with E envs per seed: {args.grad_steps} TD3 updates of batch 100 E / " \
                f"{args.grad_steps} per vector step (methods.widen_layer)"
  if args.paper_updates:
    settings += "; with E envs per seed: E TD3 updates of batch 100 per vector step"
  rows = []
  for name in args.envs:
    for method in args.methods:
      for e in args.num_envs:
        for s in args.seeds:
          # One evaluation is 50 episodes x 1000 steps per seed: minutes of MJX on a CPU.
          mjx_on_cpu = (name.startswith("Ant") and jax.default_backend() == "cpu"
                        and args.physics == "mjx")
          time_eval = not (args.no_eval or mjx_on_cpu)
          u = e if args.paper_updates else args.grad_steps
          r = measure(name, method, s, e, args.chunk, args.repeats, time_eval, u, args.physics)
          rows.append(r)
          mib = r["memory"].get("total", 0) / 2**20
          print(f"{name:9s} {r['physics']:3s} {method:5s} seeds {s:3d} x envs {e:3d} on "
                f"{r['devices']} device(s): "
                f"{r['env_steps_per_s']:8.1f} env steps/s (compile {r['compile_s']:.1f} s, "
                f"first chunk {r['first_chunk_s']:.1f} s, program {mib:.0f} MiB; one "
                f"evaluation {r['eval_s']} s)", flush=True)
          common.write_result("train_throughput", args.out, argv, quiet=True, complete=False,
                              settings=settings, results=rows)
  common.write_result("train_throughput", args.out, argv, complete=True, settings=settings,
                      results=rows)


if __name__ == "__main__":
  main()
