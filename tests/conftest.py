"""Shared test setup: persistent XLA compilation cache and session-wide compiled envs.

XLA compile time dominates this suite on a CPU (an MJX ant maze program takes tens of
seconds; the ant on MuJoCo C, the default physics on a CPU, about one), so every program is
compiled once per session (the fixtures below; a trainer built again for the same env and
static config reuses its traced programs, ``train._programs``) and the compiled executables
are cached on disk across sessions (``.jax_cache/`` or ``$JAX_COMPILATION_CACHE_DIR``).
"""

import os

# LLVM at -O0: XLA compile time is most of this suite, and -O0 halves it (the tiny point
# trainer's chunk 33 s -> 17 s, an MJX AntPush step 130 s -> 60 s, measured 2026-11-23) while
# the tests' tiny programs run as fast. The set environment reaches the processes the tests
# start (CLI runs, notebook kernels). Tests that train for real (test_learning) pass
# ``OPTIMISED`` to their programs: the point preset runs 2.5x slower at -O0.
_flags = os.environ.get("XLA_FLAGS", "")
for _flag in ("--xla_force_host_platform_device_count=1", "--xla_backend_optimization_level=0"):
  if _flag.split("=")[0] not in _flags:
    _flags = f"{_flags} {_flag}".strip()
os.environ["XLA_FLAGS"] = _flags

import jax  # noqa: E402
import pytest  # noqa: E402

from tests_support import CACHE_DIR  # noqa: E402

jax.config.update("jax_compilation_cache_dir", CACHE_DIR)
# Every program, however quick to compile (the suite has hundreds under a second), so that a
# warm session compiles nothing. The folder only grows (about 100 MB for the suite; code changes
# add entries): delete it when it is large. (JAX's size limit needs the filelock package.)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)

import envs  # noqa: E402

SMOKE_EPISODE = 3  # episode length of the compiled smoke envs: truncation shows at step 3
SMOKE_BATCH = 2


class CompiledEnv:
  """An env with its vmapped reset and step jitted once."""

  def __init__(self, name: str, physics: str | None = None):
    extra = {"physics": physics} if physics else {}
    self.env = envs.make(name, episode_length=SMOKE_EPISODE, **extra)
    self.reset = jax.jit(jax.vmap(self.env.reset))
    self.step = jax.jit(jax.vmap(self.env.step))


_compiled: dict[tuple, CompiledEnv] = {}


@pytest.fixture(scope="session")
def compiled_env():
  """compiled_env(name, physics=None) -> CompiledEnv, built once per session (an ant's
  physics: "c", "mjx", or None for the default, C on a CPU)."""

  def get(name: str, physics: str | None = None) -> CompiledEnv:
    if (name, physics) not in _compiled:
      _compiled[name, physics] = CompiledEnv(name, physics)
    return _compiled[name, physics]

  return get


@pytest.fixture(scope="module", autouse=True)
def _programs_per_module():
  """Trainers built again within a test module reuse their programs (``train._programs``);
  each module starts with none, so a worker holds no more compiled programs than the module
  it runs (a session's workers run dozens of modules, some with ant programs)."""
  from nonmono_jax.core import train
  train.forget_programs()
  yield
  train.forget_programs()


# The files of most time first, so that the two workers end together. pytest-xdist hands a
# worker the next whole file (``--dist loadfile``) once it has at most 2 tests left to run, in
# the collection's order; its default order (most tests first) left the few long tests to the
# end: the MJX trainer file (3 tests, 6.5 min) went 36th of 41 files, test_learning.py (2
# tests, 4 min) 40th, and the suite's last 2 % took 7 of its 23 min. Seconds of each file on a
# clean clone with an empty compilation cache, beside the study's two runs (2026-12-06): 440,
# 420, 280, 235, 165, 110, 110, 100; the rest under 90 each.
LONGEST_FIRST = ("test_ant_trainer.py", "test_docs.py", "test_processes.py", "test_learning.py",
                 "test_envs.py", "test_c_physics.py", "test_agent.py", "test_cli.py")


def pytest_collection_modifyitems(items):
  """The collection's files in the ``LONGEST_FIRST`` order, then the rest as found."""
  rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
  items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
