"""XLA compiler options (or config choices), A/B in one process: the training chunk compiled as
the trainer compiles it (``train.COMPILER_OPTIONS``) and with each candidate's options added
(``--try``) or its dotted config overrides applied (``--try-config``: choices that change the
program, not the train state's layout), run from one start state.

    python -m benchmarks.compiler_options --env AntPush --seeds 1 \\
        --try xla_cpu_prefer_vector_width=512 --try xla_cpu_multi_thread_eigen=false
    python -m benchmarks.compiler_options --env AntPush --seeds 4 --cpu-devices 2 \\
        --try-config low.target_noise=batch

(bfloat16 TD3 dots were tried this way, at 7167e40, and left: docs/benchmarks.md.)

For every candidate: whether its chunk computes the baseline's bits (every leaf of the states
and metrics after one chunk from the same start), and its speed against the baseline's, the
two programs' chunks alternated in this process (each round in the other order, each from a
copy of the same states): the ratio per round of wall time and of this process's CPU time,
and their medians. One process, one load: the ratios hold on a shared machine where two
processes' absolute rates do not (``benchmarks.ab`` compares two revisions of the code; this,
two compilations of one). The paper's settings as in ``train_throughput`` (warm-up and the
starting mode 0, evaluation off); a point task runs the Ant task's settings on the point robot.

Writes ``benchmarks/results/compiler_options_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from benchmarks import common
from nonmono_jax.core import train
from nonmono_jax.core.config import override
from nonmono_jax.host import methods, run


def parse_option(text: str) -> tuple[str, object]:
  """``name=value`` -> (name, value as bool, int, float or str)."""
  name, sep, value = text.partition("=")
  if not sep or not name:
    raise argparse.ArgumentTypeError(f"{text!r}: give an option as name=value")
  if value.lower() in ("true", "false"):
    return name, value.lower() == "true"
  for kind in (int, float):
    try:
      return name, kind(value)
    except ValueError:
      pass
  return name, value


def _copy(states):
  """A copy of ``states`` on their shardings (``jp.copy`` would replicate an empty array)."""
  return jax.tree.map(lambda x: jax.device_put(x, x.sharding, may_alias=False), states)


def _timed(compiled, states, t0) -> tuple[float, float]:
  """(wall s, CPU s) of one chunk from a copy of ``states`` (the chunk donates its input)."""
  s = _copy(states)
  w, c = time.perf_counter(), time.process_time()
  jax.block_until_ready(compiled(s, t0))
  return time.perf_counter() - w, time.process_time() - c


def same_bits(a, b) -> bool:
  return all(np.array_equal(np.asarray(x), np.asarray(y))
             for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def compare(env, config, seeds: int, chunk: int, candidates: list[tuple[dict, dict]],
            rounds: int) -> list:
  """One row per candidate (XLA options, config overrides): its bits against the baseline's
  and the per-round time ratios (baseline / candidate: above 1, the candidate is faster)."""
  def build(options, overrides):
    trainer = train.make_trainer(env, override(config, overrides), num_seeds=seeds,
                                 chunk_steps=chunk, compiler_options=options or None)
    return common.compile_chunk(trainer, start)
  start = train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk).init(
      jax.random.PRNGKey(0))
  base = build({}, {})
  after_base = jax.block_until_ready(base(_copy(start), 0))  # also the first (warm-up) call
  states = after_base[0]  # every timed chunk is the second, from the baseline's states
  rows = []
  for options, overrides in candidates:
    cand = build(options, overrides)
    after = jax.block_until_ready(cand(_copy(start), 0))
    times = {"baseline": [], "candidate": []}
    for r in range(rounds):
      order = ("baseline", "candidate") if r % 2 == 0 else ("candidate", "baseline")
      for name in order:
        times[name].append(_timed(base if name == "baseline" else cand, states, chunk))
    b, c = np.array(times["baseline"]), np.array(times["candidate"])
    row = {"options": options, "overrides": overrides, "same_bits": same_bits(after, after_base),
           "speedup_wall": float(np.median(b[:, 0] / c[:, 0])),
           "speedup_cpu": float(np.median(b[:, 1] / c[:, 1])),
           "rounds_wall": (b[:, 0] / c[:, 0]).tolist(), "rounds_cpu": (b[:, 1] / c[:, 1]).tolist(),
           "env_steps_per_s": {"baseline": seeds * chunk / b[:, 0].min(),
                               "candidate": seeds * chunk / c[:, 0].min()}}
    rows.append(row)
    print(f"{options or ''}{overrides or ''}: same bits {row['same_bits']}, speedup wall "
          f"{row['speedup_wall']:.3f}, CPU {row['speedup_cpu']:.3f} (median of {rounds} rounds)",
          flush=True)
  return rows


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--env", default="AntPush")
  p.add_argument("--method", default="ours", choices=methods.METHODS)
  p.add_argument("--seeds", type=int, default=1)
  p.add_argument("--chunk", type=int, default=200, help="env steps per timed call")
  p.add_argument("--rounds", type=int, default=6)
  p.add_argument("--try", dest="candidates", action="append", default=[], metavar="OPTIONS",
                 help="a candidate: name=value[,name=value...] added to the trainer's options")
  p.add_argument("--try-config", dest="configs", action="append", default=[],
                 metavar="OVERRIDES", help="a candidate: dotted config overrides "
                 "path=value[,path=value...] (e.g. low.target_noise=batch)")
  p.add_argument("--cpu-devices", type=int, default=1, metavar="N")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  if not args.candidates and not args.configs:
    p.error("give a candidate: --try OPTIONS or --try-config OVERRIDES")
  parse = lambda c: dict(parse_option(o) for o in c.split(","))
  candidates = ([(parse(c), {}) for c in args.candidates]
                + [({}, parse(c)) for c in args.configs])
  run.use_cpu_devices(args.cpu_devices)
  env, config = common.paper_setup(args.env, args.method)
  rows = compare(env, config, args.seeds, args.chunk, candidates, args.rounds)
  common.write_result("compiler_options", args.out, argv, env=args.env, method=args.method,
                      seeds=args.seeds, chunk=args.chunk, baseline=train.COMPILER_OPTIONS,
                      results=rows, complete=True)


if __name__ == "__main__":
  main()
