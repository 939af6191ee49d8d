"""Does a training program give the same bits on another CPU type, or after a change of the
code? A hash of its train state.

    python -m benchmarks.state_hash --label native
    python -m benchmarks.state_hash --label native --task AntPush     # the Ant study's settings
    XLA_FLAGS=--xla_cpu_max_isa=AVX2 python -m benchmarks.state_hash --label native-avx2
    qemu-x86_64 -cpu EPYC-Rome "$(which python)" -m benchmarks.state_hash --label qemu-EPYC-Rome

Trains ours and prints the SHA-256 (16 hex digits) of every leaf of the final train state.
Equal hashes: the same bits. ``--task PointMaze`` (the default): the point preset, 2 seeds, a
200-step warm-up and a 300-step starting mode, 1500 steps (every level updates; a few seconds).
``--task AntPush``: the side-by-side study's settings in small (the paper preset, 6 seeds on one
device, MuJoCo C with ``mujoco200`` contacts, the held-goal evaluation beside), a 1000-step
warm-up, a 500-step starting mode and 2000 steps (a few minutes). A change can keep the
first's bits and not the second's: the dots' shapes differ (``ec38806``, docs/benchmarks.md,
"Third step"), so a change meant to keep the bits is checked on both. Run it on two machines,
or here and under
QEMU's user-mode emulation of another CPU (Debian's ``qemu-user``; about 100x slower, 30 min),
with the same ``XLA_FLAGS``. XLA:CPU picks its code for the CPU it finds (LLVM's target CPU
and instruction sets, YNNPACK's kernels), which the emulator reports as the emulated one. The
result is appended, with the label, the flags and the host, to
``results/state_hash_<platform>_<date>.json``. ``/proc/cpuinfo`` under QEMU is the real
host's, so the label is what names the emulated CPU.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import time

import jax
import numpy as np

import envs
from benchmarks import common
from nonmono_jax.core import train
from nonmono_jax.host import plan

# task -> (its env, the paper preset's overrides, seeds, chunk, steps)
CHECKS = {
    "PointMaze": (lambda: envs.make("PointMaze", episode_length=100),
                  {"warmup_steps": 200, "top.starting_steps": 300, "eval_every": 100_000},
                  2, 500, 1500),
    "AntPush": (lambda: plan.make_env("AntPush", 1000, "c", "mujoco200"),
                {"warmup_steps": 1000, "top.starting_steps": 500, "eval_every": 1000,
                 "eval_episodes": 2, "eval_extra": ("held",)}, 6, 1000, 2000),
}


def state_hash(task: str = "PointMaze") -> str:
  """SHA-256 (16 hex digits) of the train state of ours after the ``CHECKS`` run of ``task``."""
  make_env, overrides, seeds, chunk, steps = CHECKS[task]
  config = common.paper_config("ours", task, overrides)
  trainer = train.make_trainer(make_env(), config, num_seeds=seeds, chunk_steps=chunk)
  states = trainer.init(jax.random.PRNGKey(0))
  for t0 in range(0, steps, chunk):
    states, _ = trainer.chunk(states, t0)
  digest = hashlib.sha256()
  for leaf in jax.tree.leaves(jax.device_get(states)):
    digest.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
  return digest.hexdigest()[:16]


def main(argv=None) -> None:
  p = argparse.ArgumentParser(prog="python -m benchmarks.state_hash", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
  p.add_argument("--label", required=True, help="what this run is, e.g. native, qemu-EPYC-Rome")
  p.add_argument("--task", choices=tuple(CHECKS), default="PointMaze",
                 help="the program hashed (the module's docstring)")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  start = time.perf_counter()
  entry = {"label": args.label, "command": common.command("state_hash", argv),
           "task": args.task, "xla_flags": os.environ.get("XLA_FLAGS", ""),
           "hash": state_hash(args.task),
           "seconds": round(time.perf_counter() - start, 1)}
  print(json.dumps(entry))
  path = common.result_path("state_hash", args.out)
  entries = json.load(open(path))["entries"] if os.path.exists(path) else []
  common.write_result("state_hash", args.out, argv, entries=entries + [entry])


if __name__ == "__main__":
  main()
