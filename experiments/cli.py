"""The experiment command shared by ``python -m experiments.<task>``: train methods, log, resume.

    python -m experiments.pointmaze --method ours hiro --preset quick --out runs/pm
    python -m experiments.antpush --method ours --seeds 5 --out runs/push     # paper preset
    python -m experiments.antpush --resume runs/push                          # after a stop
    python -m experiments.antpush --top.alpha 0 0.4 0.7 --low.batch_size 256  # any field
    python -m experiments.pointpush --method ours --sweep top.alpha=0,0.4,0.7 0,0.2,0.35

Methods (and sweep variants) whose programs coincide (``hyper.static_key``: ours and its
ablations; a sweep of traced numbers) run as lanes of one program; the others one after
another; all into one folder (``nonmono_jax.host.io``): ``config.json``,
``metrics.csv`` (one row per method, seed and chunk), ``metrics.jsonl`` (every metric) and
``checkpoints/<method>/``. The run itself is the library ``nonmono_jax.host.run`` (the plan, from
the presets or from ``config.json``; the folder; the training loop; the output sinks): this
module turns flags into a plan and outcomes into exit codes.

- Every value is checked before anything compiles or the folder is created: the configs'
  own ranges, ``nonmono_jax.core.validation`` (finite floats, int32 ints, full dotted names) and
  the memory the run needs (``jax.eval_shape`` of the trainer's init) against what is free.
- One process writes a run folder at a time (``nonmono_jax.host.runlock``, held for the whole run).
- ``--resume`` restores the newest checkpoint that restores, and accepts only the flags that
  do not change the run (``--time-limit``, ``--no-progress``, ``--tensorboard``).
- Every failure is one line; exit codes: 0 done, 1 failed run (NaN or Inf in a learner,
  a full disk, any other error: the last good checkpoint is kept), 2 bad input (a value, a
  folder, a broken ``config.json`` / ``metrics.csv`` / checkpoint, a folder in use),
  3 stopped for ``--time-limit`` (each process runs at least one chunk first).
"""

from __future__ import annotations

import argparse
import collections.abc
import dataclasses
import errno
import importlib.util
import math
import os
import sys
import typing

from experiments import cores

cores.share(sys.argv[1:])  # before JAX loads: this process's share of a machine it shares

import envs  # noqa: E402
from envs import ant_maze  # noqa: E402
from envs import contacts as contacts_lib  # noqa: E402
from nonmono_jax.core import config as config_lib  # noqa: E402
from nonmono_jax.host import io, methods, plan as plan_lib, processes, run, runlock, sinks  # noqa: E402
from nonmono_jax.host import programs as programs_lib  # noqa: E402
from nonmono_jax.host.methods import task_of_module  # noqa: E402,F401 - for experiments/<task>.py
from nonmono_jax.host.plan import Plan  # noqa: E402,F401 - for callers of plan_from_args
from nonmono_jax.host.run import Clock, NonFinite, TimeLimit  # noqa: E402,F401 - the run's, in tests

EXIT_FAILED, EXIT_BAD_INPUT, EXIT_TIME_LIMIT = 1, 2, 3
EXIT_NON_FINITE = EXIT_FAILED
# What --resume may change: how this process runs, not what the run is.
RESUME_ALLOWED = ("resume", "time_limit", "no_progress", "tensorboard", "distributed",
                  "coordinator", "num_processes", "process_id")


# --- config fields as command-line flags ------------------------------------------------------

def _bool(text: str) -> bool:
  if text.lower() in ("1", "true", "yes", "on"):
    return True
  if text.lower() in ("0", "false", "no", "off"):
    return False
  raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


def _fields(cls, prefix=""):
  """(dotted name, type) of every leaf field of a config dataclass, recursively."""
  hints = typing.get_type_hints(cls)
  for f in dataclasses.fields(cls):
    t = hints[f.name]
    if dataclasses.is_dataclass(t):
      yield from _fields(t, prefix + f.name + ".")
    else:
      yield prefix + f.name, t


def _add_field_flags(parser: argparse.ArgumentParser, example: config_lib.AgentConfig):
  group = parser.add_argument_group(
      "agent config fields (defaults: this task's preset for ours; each method's preset may "
      "differ, see nonmono_jax/host/methods.py)")
  for name, t in _fields(config_lib.AgentConfig):
    default = config_lib.get(example, name)
    kwargs = dict(dest="field:" + name, default=argparse.SUPPRESS,
                  help=f"(default: {default})")
    origin = typing.get_origin(t)
    if t is bool:
      kwargs.update(type=_bool, metavar="BOOL")
    elif origin in (tuple, list, collections.abc.Sequence):
      elem = typing.get_args(t)[0]
      kwargs.update(type=elem, nargs="+")
    elif t in (int, float, str):
      kwargs.update(type=t)
    else:
      continue
    group.add_argument(f"--{name}", **kwargs)


# --- the parser --------------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
  """argparse with every error on one line (no usage block): ``prog: error: message``."""

  def error(self, message):
    self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _command(task: str) -> str:
  """The command that runs ``task``: its module, or the registry's generic one."""
  module = f"experiments.{task.lower()}"
  return (f"python -m {module}" if importlib.util.find_spec(module) is not None
          else f"python -m experiments {task}")


def make_parser(task: str) -> argparse.ArgumentParser:
  p = _Parser(
      prog=_command(task),
      description=f"Train methods of Kim et al. (2023) on {task}; seeds are vmapped.",
      formatter_class=argparse.ArgumentDefaultsHelpFormatter)
  p.add_argument("--method", nargs="+", default=["ours"], choices=methods.METHODS,
                 help="one or more into --out: those that differ only in traced numbers "
                      "(ours and its ablations) as lanes of one program, the others one after "
                      "another")
  p.add_argument("--sweep", nargs="+", action="append", default=None,
                 metavar="FIELD=VALUE [VALUE ...]",
                 help="variants of each method, one per value of a dotted config field (a "
                      "tuple's entries joined by commas: --sweep top.alpha=0,0.4,0.7 0,0.2,0.35); "
                      "given twice, the grid of both; named method+field=value")
  p.add_argument("--preset", default="paper", choices=methods.PRESETS,
                 help="paper: the paper's numbers (docs/spec.md); quick: minutes on a CPU")
  p.add_argument("--seeds", type=int, default=None, help="vmapped seeds (default: preset)")
  p.add_argument("--steps", type=int, default=None,
                 help="vector env steps per seed (default: preset)")
  p.add_argument("--chunk", type=int, default=None,
                 help="steps per jitted call and metrics row (default: preset)")
  p.add_argument("--checkpoint-every", type=int, default=None,
                 help="steps between checkpoints, a multiple of --chunk (default: preset)")
  p.add_argument("--episode-length", type=int, default=None, help="(default: preset)")
  p.add_argument("--envs-per-seed", type=int, default=None, metavar="E",
                 help="E envs per seed with the preset's schedule and gradient samples per env "
                      "step (methods.widen; --steps etc. then count vector steps of E envs)")
  p.add_argument("--grad-steps", type=int, default=None, metavar="U",
                 help="with --envs-per-seed: TD3 updates per vector step, each of batch x E/U "
                      "(default E: the paper's updates exactly)")
  p.add_argument("--seed", type=int, default=0, help="PRNG seed of the run")
  p.add_argument("--out", default=None, help="output folder (default: runs/<task>-<time>)")
  p.add_argument("--resume", default=None, metavar="DIR",
                 help="continue the run in DIR with its saved configuration")
  p.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                 help="stop, checkpointed, before a chunk that would end past this many seconds "
                      f"of wall time; exit code {EXIT_TIME_LIMIT}, continue with --resume")
  p.add_argument("--cpu-devices", type=int, default=None, metavar="N",
                 help="on the CPU, split the lanes over N devices, e.g. one per core (about "
                      "1.6-2.5x faster at 16 seeds on 2 cores; --seeds a multiple of N; not "
                      "bit-identical to 1 device); --resume uses the run's count")
  if envs.has_physics(task):
    p.add_argument("--physics", default="auto", choices=ant_maze.PHYSICS,
                   help="the ant's physics: c, MuJoCo's C engine called from inside the jitted "
                        "step (10-25x MJX on a CPU); mjx, the MJX pipeline (for accelerators); "
                        "auto: c on a CPU, mjx on an accelerator; --resume keeps the run's")
    p.add_argument("--contacts", default=None, choices=contacts_lib.CONTACTS,
                   help="the ant's engine settings: mujoco200 (default), those that make "
                        "MuJoCo 3 move the ant and blocks as MuJoCo 2.x and MuJoCo 2.0's "
                        "capsule inertia, what the paper's code ran; mujoco2, without the "
                        "inertia (the settings checked against MuJoCo 2.3.7); mujoco3, MuJoCo "
                        "3's own (docs/environments.md); --resume keeps the run's")
  _add_process_flags(p)
  p.add_argument("--no-progress", action="store_true", help="no progress bar")
  p.add_argument("--tensorboard", action="store_true",
                 help="also write TensorBoard event files to OUT/tensorboard/<method>")
  _add_field_flags(p, methods.make_config("ours", task))
  return p


def _add_process_flags(p: argparse.ArgumentParser) -> None:
  """--distributed and the three flags that say where the processes are."""
  p.add_argument("--distributed", action="store_true",
                 help="one run over several processes (JAX's multi-process runtime): the "
                      "lanes are split over every process's devices, process 0 writes the run "
                      "folder (which all must see); on SLURM or Open MPI the processes find "
                      "each other, elsewhere give the three flags below (docs/cluster.md)")
  p.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                 help="with --distributed: process 0's address and a free port")
  p.add_argument("--num-processes", type=int, default=None, metavar="N",
                 help="with --distributed: the run's process count")
  p.add_argument("--process-id", type=int, default=None, metavar="I",
                 help="with --distributed: this process's index, 0 to N - 1")


def plan_from_args(task: str, args: argparse.Namespace) -> plan_lib.Plan:
  """The new run the flags describe (``plan.new_run``); raises ValueError naming the field."""
  overrides = {k[len("field:"):]: v for k, v in vars(args).items() if k.startswith("field:")}
  return plan_lib.new_run(
      task, args.method, preset=args.preset, out=args.out, seed=args.seed, overrides=overrides,
      run={name: getattr(args, name, None) for name in plan_lib.RUN_FIELDS},
      envs_per_seed=getattr(args, "envs_per_seed", None),
      grad_steps=getattr(args, "grad_steps", None), sweep=parse_sweep(args.sweep),
      physics=getattr(args, "physics", None), contacts=getattr(args, "contacts", None))


def parse_sweep(given) -> dict:
  """``[["top.alpha=0,0.4,0.7", "0,0.2,0.35"], ...]`` -> {"top.alpha": [(0, 0.4, 0.7), ...]};
  each value parsed by its field's type, as the field's own flag parses it."""
  types = dict(_fields(config_lib.AgentConfig))
  sweep = {}
  for tokens in given or []:
    path, sep, first = tokens[0].partition("=")
    if not sep or not path:
      raise ValueError(f"--sweep takes FIELD=VALUE [VALUE ...], got {' '.join(tokens)}")
    if path not in types:
      raise ValueError(f"--sweep {path}: not a config field with a value (see --help)")
    if path in sweep:
      raise ValueError(f"--sweep {path} is given twice")
    try:
      sweep[path] = [_typed(types[path], text) for text in [first] + tokens[1:]]
    except (ValueError, argparse.ArgumentTypeError) as e:
      raise ValueError(f"--sweep {path}: {e}") from None
  return sweep


def _typed(t, text: str):
  """A field's value from text by its type: a sequence's entries joined by commas."""
  if typing.get_origin(t) in (tuple, list, collections.abc.Sequence):
    elem = typing.get_args(t)[0]
    return tuple(elem(x) for x in text.split(","))
  return _bool(text) if t is bool else t(text)


# --- the command: checks, the run folder, the run ----------------------------------------------

CACHE_DIR = os.path.join(os.path.expanduser("~"), ".cache", "nonmono-jax", "xla")


def main(task: str, argv=None) -> int:
  io.quiet_storage_leftovers()
  _cache_compiled_programs()
  parser = make_parser(task)
  args = parser.parse_args(argv)
  try:
    _use_cpu_devices(args)
    _join(args)
    plan = _plan(task, args, argv)
    programs = programs_lib.Programs(plan)
    programs_lib.check_memory(plan, programs)
  except ValueError as e:
    parser.error(str(e))
  for warning in plan.warnings:
    print(f"warning: {warning}", file=sys.stderr, flush=True)
  code = EXIT_BAD_INPUT
  try:
    with run.open_folder(plan, resume=args.resume is not None):
      code = _run(plan, args, programs)
  except (run.BadFolder, runlock.Locked, io.MetricsError, io.CheckpointError) as e:
    parser.error(str(e))
  finally:
    processes.leave(code)
  return code


def _cache_compiled_programs() -> None:
  """JAX's persistent compilation cache, on unless the user set one (``JAX_COMPILATION_CACHE_DIR``):
  a resumed run, and the memory check's compile of a large run, reuse the compiled chunk."""
  import jax
  if not jax.config.jax_compilation_cache_dir:
    jax.config.update("jax_compilation_cache_dir", CACHE_DIR)


def _use_cpu_devices(args: argparse.Namespace) -> None:
  """The CPU device count, before JAX starts: ``--cpu-devices``, or on ``--resume`` the count
  the run trained on (``config.json``; per process), so that it continues as it ran."""
  n = args.cpu_devices
  if args.resume:
    payload = plan_lib.read_config(args.resume)
    if isinstance(payload, dict) and payload.get("platform") == "cpu":
      n = payload.get("device_count")
      procs = payload.get("processes", 1)
      if isinstance(n, int) and isinstance(procs, int) and procs > 1:
        n //= procs
  if isinstance(n, int):
    run.use_cpu_devices(n)


def _join(args: argparse.Namespace) -> None:
  """``--distributed``: join the run's other processes, before JAX starts (processes.join)."""
  given = [f"--{n.replace('_', '-')}" for n in ("coordinator", "num_processes", "process_id")
           if getattr(args, n) is not None]
  if not args.distributed:
    if given:
      raise ValueError(f"{', '.join(given)} need --distributed")
    return
  processes.join(args.coordinator, args.num_processes, args.process_id)


def _plan(task: str, args: argparse.Namespace, argv) -> plan_lib.Plan:
  """The checked plan of a new run or of ``--resume``; raises ValueError with one line."""
  limit = args.time_limit
  if limit is not None and not (math.isfinite(limit) and limit > 0):
    raise ValueError(f"--time-limit must be a positive number of seconds, got {limit}")
  if args.resume is None:
    plan = plan_from_args(task, args)
    if os.path.lexists(plan.out) and processes.writer():  # process 0 creates it
      if not os.path.isdir(plan.out):
        raise ValueError(f"--out {plan.out} exists and is not a folder")
      if set(os.listdir(plan.out)) - {runlock.NAME}:  # a lock alone: a start that failed
        raise ValueError(f"--out {plan.out} exists and is not empty (use --resume {plan.out} "
                         f"to continue it, or another --out)")
    return plan
  if not args.resume:
    raise ValueError("--resume must name a run folder")
  given = sorted(_given_dests(task, argv) - set(RESUME_ALLOWED))
  if given:
    flags = ", ".join("--" + (d[len("field:"):] if d.startswith("field:") else
                              d.replace("_", "-")) for d in given)
    raise ValueError(f"{flags} cannot change on --resume: the run's plan is "
                     f"{os.path.join(args.resume, 'config.json')} (only --time-limit, "
                     f"--no-progress and --tensorboard may be given)")
  return plan_lib.load_run(args.resume, task=task)


def _given_dests(task: str, argv) -> set[str]:
  """The destinations of the options written on the command line (defaults left out)."""
  p = make_parser(task)
  for action in p._actions:
    action.default = argparse.SUPPRESS
  return set(vars(p.parse_args(argv)))


def _run(plan: plan_lib.Plan, args: argparse.Namespace, programs=None) -> int:
  """Trains every method of the plan; the exit code (0, 1 failed, 3 time limit)."""
  writer = processes.writer()  # the others of a multi-process run write nothing of their own
  outputs, log = [], lambda *a, **k: None
  if writer:
    outputs = [sinks.MetricsCsv(plan.out, plan), sinks.JsonLines(plan.out),
               sinks.Progress(plan, enabled=not args.no_progress)]
    if args.tensorboard:
      outputs.append(sinks.TensorBoard(plan.out))
    log = print
  physics = f", {plan.physics} physics" if plan.physics else ""
  if plan.contacts is not None:
    physics += f", {plan.contacts} contacts"
  across = f", {processes.count()} processes" if processes.count() > 1 else ""
  log(f"{plan.task}: {', '.join(plan.configs)} x {plan.spec.seeds} seeds x {plan.spec.steps} "
      f"steps ({plan.preset}{physics}{across}) -> {plan.out}", flush=True)
  clock = Clock.starting_now(args.time_limit,
                             os.path.join(plan.out, "timing.json") if writer else None)
  processes.watch(lambda why: print(f"error: ProcessLost: {why}; {_saved(plan)}; continue "
                                    f"with --resume {plan.out}", file=sys.stderr, flush=True))
  try:
    with run.remembering_ctrl_c(), sinks.closing(outputs):
      run.run_plan(plan, outputs, clock, log, programs)
  except NonFinite as e:
    print(f"error: {e}", file=sys.stderr)
    return EXIT_FAILED
  except TimeLimit as e:
    log(f"time limit: {e}", flush=True)
    return EXIT_TIME_LIMIT
  except (io.MetricsError, io.CheckpointError):
    raise
  except (Exception, KeyboardInterrupt) as e:  # noqa: BLE001 - one line, not a traceback
    if os.environ.get("NONMONO_TRACEBACK"):
      raise
    print(f"error: {_describe(e)}; {_saved(plan)}; continue with --resume {plan.out} "
          f"(NONMONO_TRACEBACK=1 shows the traceback)", file=sys.stderr, flush=True)
    return EXIT_FAILED
  log(f"done: {os.path.join(plan.out, 'metrics.csv')}", flush=True)
  return 0


def _describe(e: BaseException) -> str:
  """One line for an exception: a full disk said as such, else its type and first line."""
  if isinstance(e, run.Terminated):
    return "terminated (SIGTERM)"
  if isinstance(e, KeyboardInterrupt):
    return "interrupted"
  chain = [e]
  while chain[-1].__cause__ or chain[-1].__context__:
    chain.append(chain[-1].__cause__ or chain[-1].__context__)
  for x in chain:
    if getattr(x, "errno", None) == errno.ENOSPC or "No space left" in str(x):
      where = getattr(x, "filename", None)
      return f"the disk is full{f' (writing {where})' if where else ''}"
  first = (str(e).strip().splitlines() or [""])[0][:200]
  return f"{type(e).__name__}: {first}"


def _saved(plan: plan_lib.Plan) -> str:
  """Each method's last complete checkpoint, as the folder holds them now."""
  parts = []
  for method in plan.configs:
    d = os.path.join(plan.out, "checkpoints", method)
    steps = [int(n) for n in (os.listdir(d) if os.path.isdir(d) else []) if n.isdigit()
             and os.path.exists(os.path.join(d, n, "commit_success.txt"))]
    parts.append(f"{method} step {max(steps)}" if steps else f"{method} none")
  return "last good checkpoints: " + ", ".join(parts)
