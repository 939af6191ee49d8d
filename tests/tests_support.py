"""Shared test constants (importable from tests and notebooks' tests)."""

import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# XLA's persistent compilation cache: shared by the test process and the ones it starts.
CACHE_DIR = os.environ.get("JAX_COMPILATION_CACHE_DIR", os.path.join(ROOT, ".jax_cache"))

# A tiny experiment: 2 seeds x 800 steps of the point robot with 16-unit networks.
TINY_RUN = ["--preset", "quick", "--seeds", "2", "--steps", "800", "--chunk", "200",
            "--checkpoint-every", "200", "--episode-length", "100", "--warmup_steps", "100",
            "--top.starting_steps", "100", "--eval_every", "200", "--eval_episodes", "2",
            "--low.hidden", "16", "16", "--middle.hidden", "16", "16", "--low.batch_size", "8",
            "--middle.batch_size", "8", "--middle_ppo.hidden", "16", "--top.ppo.hidden", "16",
            "--no-progress"]
# The same through the run library (nonmono_jax.host.run.new_run): run size, dotted overrides.
TINY_SIZE = {"seeds": 2, "steps": 800, "chunk": 200, "checkpoint_every": 200,
             "episode_length": 100}
TINY_OVERRIDES = {"warmup_steps": 100, "top.starting_steps": 100, "eval_every": 200,
                  "eval_episodes": 2, "low.hidden": (16, 16), "middle.hidden": (16, 16),
                  "low.batch_size": 8, "middle.batch_size": 8, "middle_ppo.hidden": (16,),
                  "top.ppo.hidden": (16,)}

# XLA's default optimisation, for tests that train for real: the suite compiles at LLVM -O0
# (conftest.py), at which the point preset's training step runs 2.5x slower.
OPTIMISED = {"xla_backend_optimization_level": 3}
