"""What every benchmark records: the machine, the command, the date, and the result file."""

from __future__ import annotations

import dataclasses
import datetime
import glob
import json
import os
import platform
import subprocess
import sys
from typing import Any

import jax

from nonmono_jax.core.config import AgentConfig, get
from nonmono_jax.host import methods
from nonmono_jax.host.provenance import host

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(os.path.dirname(__file__), "results")
# Dotted overrides that time every step with all modes live: no warm-up, no starting mode,
# evaluation never (timed apart).
ALL_MODES_LIVE = {"warmup_steps": 0, "eval_every": 10**9, "top.starting_steps": 0}
BUFFERS = ("low.buffer_size", "middle.buffer_size")


def description(doc: str) -> str:
  """A benchmark's ``--help`` description: its docstring's first paragraph on one line."""
  return " ".join(doc.strip().split("\n\n")[0].split())


def paper_config(method: str, task: str, overrides: dict | None = None) -> AgentConfig:
  """The paper preset's config of ``method`` on ``task`` (``methods.build_config``) with the
  replay buffers its task declares, rings of a fixed size (a benchmark runs a few chunks, not
  the whole run that ``build_config`` sizes them for), then ``overrides``."""
  layers, _ = methods.preset_layers("paper", method, task)
  ring = {p: layers.get(p, get(AgentConfig(), p)) for p in BUFFERS}
  return methods.build_config("paper", method, task, {**ring, **(overrides or {})})[0]


def paper_env(env_name: str, physics: str = "c"):
  """The env the speed benchmarks time: ``env_name`` with the paper's 1000-step episodes, an
  ant on ``physics`` ("c", "mjx" or "auto")."""
  from nonmono_jax.host import plan
  return plan.make_env(env_name, 1000, physics if env_name.startswith("Ant") else None)


def paper_task(env_name: str) -> str:
  """The task whose paper preset the speed benchmarks time ``env_name`` with: its Ant twin (a
  point task is timed at the Ant's settings, so that the two differ by the physics only)."""
  return env_name.replace("Point", "Ant")


def paper_setup(env_name: str, method: str, physics: str = "c",
                overrides: dict | None = None):
  """``paper_env`` and ``method``'s config at the paper's settings: the paper preset of
  ``paper_task`` (``paper_config``) with every mode live (``ALL_MODES_LIVE``), then
  ``overrides``."""
  return (paper_env(env_name, physics),
          paper_config(method, paper_task(env_name), {**ALL_MODES_LIVE, **(overrides or {})}))


def export_revision(ref: str, folder: str) -> str:
  """Git revision ``ref`` of this repository, exported into ``folder`` (made if missing)."""
  os.makedirs(folder, exist_ok=True)
  archive = subprocess.run(["git", "-C", ROOT, "archive", ref], check=True,
                           capture_output=True).stdout
  subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
  return folder


def machine() -> dict:
  dev = jax.devices()[0]
  return {"platform": dev.platform, "device": str(dev.device_kind), "cpu_count": os.cpu_count(),
          "processor": platform.processor() or platform.machine(),
          "python": platform.python_version(), "jax": jax.__version__, "host": host()}


def command(name: str, argv: list[str] | None) -> str:
  """The command line that ran benchmark ``name`` (``argv``, or the process's own)."""
  return " ".join(["python -m", f"benchmarks.{name}", *(sys.argv[1:] if argv is None else argv)])


def result_path(name: str, out_dir: str) -> str:
  """``<out_dir>/<name>_<platform>_<date>.json``: where today's result of ``name`` goes."""
  return os.path.join(out_dir, f"{name}_{jax.devices()[0].platform}_"
                               f"{datetime.date.today().isoformat()}.json")


def write_result(name: str, out_dir: str, argv: list[str] | None, quiet: bool = False,
                 **payload) -> str:
  """Write ``result_path(name, out_dir)`` with the command that made it.

  Benchmarks call it after every row (``quiet``) and once at the end, so a run killed at a
  time limit keeps the rows it measured (``"complete": false`` until the last call).
  """
  path = result_path(name, out_dir)
  result = {"benchmark": name, "date": datetime.date.today().isoformat(), "machine": machine(),
            "command": command(name, argv), **payload}
  os.makedirs(out_dir, exist_ok=True)
  with open(path + ".tmp", "w") as f:
    json.dump(result, f, indent=2)
  os.replace(path + ".tmp", path)
  if not quiet:
    print("wrote", path)
  return path


def run_fresh(root: str, name: str, args: list[str], out: str) -> dict:
  """The result file of one run of benchmark ``name`` (``python -m benchmarks.<name> <args>
  --out <out>``) in a fresh process on the code under ``root``."""
  env = {**os.environ, "PYTHONPATH": root}
  r = subprocess.run([sys.executable, "-m", f"benchmarks.{name}", *args, "--out", out],
                     check=False, cwd=root, env=env, capture_output=True, text=True)
  if r.returncode != 0:
    raise SystemExit(f"benchmarks.{name} in {root} failed:\n{r.stderr[-2000:]}")
  (path,) = glob.glob(os.path.join(out, f"{name}_*.json"))
  with open(path) as f:
    return json.load(f)


def rows(result: dict) -> list[dict]:
  """A result file's rows (``results``, or ``rows`` in the older benchmarks)."""
  return result.get("results") or result["rows"]


def memory_stats() -> dict:
  """The accelerator's allocator statistics (``peak_bytes_in_use`` is the process's peak so
  far); empty on a CPU, whose runtime keeps none."""
  stats = jax.devices()[0].memory_stats() or {}
  return {k: stats[k] for k in ("peak_bytes_in_use", "bytes_in_use", "bytes_limit") if k in stats}


@dataclasses.dataclass(frozen=True)
class CompiledChunk:
  """A trainer's chunk compiled ahead of time: called as ``chunk(states, t0)``, as the trainer's
  own; ``memory_analysis`` and ``as_text`` are XLA's, of the compiled program."""

  compiled: Any  # jax.stages.Compiled of chunk_program(states, t0, hp)
  hp: Any  # the lanes' Numbers it is called with

  def __call__(self, states, t0):
    return self.compiled(states, t0, self.hp)

  def memory_analysis(self):
    return self.compiled.memory_analysis()

  def as_text(self) -> str:
    return self.compiled.as_text()


def compile_chunk(trainer, states) -> CompiledChunk:
  """``trainer``'s chunk compiled for ``states`` (its time is the compile time)."""
  return CompiledChunk(trainer.chunk_program.lower(states, 0, trainer.hp).compile(), trainer.hp)
