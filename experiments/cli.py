"""The experiment command shared by ``python -m experiments.<task>``: train methods, log, resume.

    python -m experiments.pointmaze --method ours hiro --preset quick --out runs/pm
    python -m experiments.antpush --method ours --seeds 5 --out runs/push     # paper preset
    python -m experiments.antpush --resume runs/push                          # after a stop
    python -m experiments.antpush --top.alpha 0 0.4 0.7 --low.batch_size 256  # any field
    python -m experiments.pointpush --method ours --sweep top.alpha=0,0.4,0.7 0,0.2,0.35

Methods (and sweep variants) whose programs coincide (``lanes.static_key``: ours and its
ablations; a sweep of traced numbers) run as lanes of one program; the others one after
another; all into one folder (``nonmono_jax.host.folder``): ``config.json``,
``metrics.csv`` (one row per method, seed and chunk), ``metrics.jsonl`` (every metric) and
``checkpoints/<method>/``. The run itself is the library ``nonmono_jax.host.run`` (the plan, from
the presets or from ``config.json``; the folder; the training loop; the output sinks): this
module turns flags into a plan and outcomes into exit codes. The flags themselves are
``experiments/flags.py`` (no JAX: ``experiments/launch.py`` answers ``--help`` and bad flags
before this module loads).

- Every value is checked before anything compiles or the folder is created: the configs'
  own ranges, ``nonmono_jax.core.validation`` (finite floats, int32 ints, full dotted names) and
  the memory the run needs (``jax.eval_shape`` of the trainer's init) against what is free.
- One process writes a run folder at a time (``nonmono_jax.host.runlock``, held for the whole run).
- ``--resume`` restores the newest checkpoint that restores, and accepts only the flags that
  do not change the run (``--time-limit``, ``--no-progress``, ``--tensorboard``, ``--wandb``,
  and the multi-process flags ``--distributed``, ``--coordinator``, ``--num-processes``,
  ``--process-id``: ``RESUME_ALLOWED``).
- Every failure is one line; exit codes: 0 done, 1 failed run (NaN or Inf in a learner,
  a full disk, Ctrl-C or SIGTERM (``nonmono_jax.host.interrupts``), any other error: the last
  good checkpoint is kept), 2 bad input (a value, a
  folder, a broken ``config.json`` / ``metrics.csv`` / checkpoint, a folder in use),
  3 stopped for ``--time-limit`` (each process runs at least one chunk first).
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import sys

from experiments import cores

cores.share(sys.argv[1:])  # before JAX loads: this process's share of a machine it shares

from experiments.flags import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_TIME_LIMIT  # noqa: E402,F401
from experiments.flags import make_parser, parse_sweep  # noqa: E402,F401 - the command's flags
from nonmono_jax.host import interrupts  # noqa: E402
from nonmono_jax.host import checkpoints, folder, plan as plan_lib, processes, rows  # noqa: E402
from nonmono_jax.host import run, runlock  # noqa: E402
from nonmono_jax.host import sinks  # noqa: E402
from nonmono_jax.host import programs as programs_lib  # noqa: E402
from nonmono_jax.host.methods import task_of_module  # noqa: E402,F401 - for experiments/<task>.py
from nonmono_jax.host.plan import Plan  # noqa: E402,F401 - for callers of plan_from_args
from nonmono_jax.host.run import Clock, NonFinite, TimeLimit  # noqa: E402,F401 - the run's, in tests

# What --resume may change: how this process runs, not what the run is.
RESUME_ALLOWED = ("resume", "time_limit", "no_progress", "tensorboard", "wandb", "distributed",
                  "coordinator", "num_processes", "process_id")


def plan_from_args(task: str, args: argparse.Namespace) -> plan_lib.Plan:
  """The new run the flags describe (``plan.new_run``); raises ValueError naming the field."""
  overrides = {k[len("field:"):]: v for k, v in vars(args).items() if k.startswith("field:")}
  return plan_lib.new_run(
      task, args.method, preset=args.preset, out=args.out, seed=args.seed, overrides=overrides,
      run={name: getattr(args, name, None) for name in plan_lib.RUN_FIELDS},
      envs_per_seed=getattr(args, "envs_per_seed", None),
      grad_steps=getattr(args, "grad_steps", None), sweep=parse_sweep(args.sweep),
      physics=getattr(args, "physics", None), contacts=getattr(args, "contacts", None))


# --- the command: checks, the run folder, the run ----------------------------------------------

CACHE_DIR = os.path.join(os.path.expanduser("~"), ".cache", "nonmono-jax", "xla")


def main(task: str, argv=None) -> int:
  checkpoints.quiet_storage_leftovers()
  _cache_compiled_programs()
  parser = make_parser(task)
  args = parser.parse_args(argv)
  try:
    for flag in sinks.OPTIONAL:  # --tensorboard, --wandb: their packages, before anything runs
      if getattr(args, flag):
        sinks.check_available(flag)
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
    # From the folder's opening, a Ctrl-C or SIGTERM is taken where nothing is half-written
    # (nonmono_jax.host.interrupts); before it, it ends the command at once.
    with interrupts.during_run(lambda exc: _stopped(plan, exc)):
      try:
        with run.open_folder(plan, resume=args.resume is not None):
          code = _run(plan, args, programs)
      except KeyboardInterrupt as e:  # as the folder opened, before the run began
        interrupts.say(_stopped(plan, type(e)))
        code = EXIT_FAILED
  except (run.BadFolder, runlock.Locked, rows.MetricsError, checkpoints.CheckpointError) as e:
    parser.error(str(e))
  finally:
    processes.leave(code)
  return code


def _stopped(plan: plan_lib.Plan, exc: type) -> str:
  """The line of a run stopped by Ctrl-C or SIGTERM: what is saved, how to continue."""
  return (f"error: {interrupts.describe(exc)}; {_saved(plan)}; continue with --resume "
          f"{plan.out}")


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
    payload = folder.read_config(args.resume)
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
    if processes.writer():  # process 0 creates it
      run.check_new_out(plan.out)
    return plan
  if not args.resume:
    raise ValueError("--resume must name a run folder")
  given = sorted(_given_dests(task, argv) - set(RESUME_ALLOWED))
  if given:
    named = ", ".join("--" + (d[len("field:"):] if d.startswith("field:") else
                              d.replace("_", "-")) for d in given)
    raise ValueError(f"{named} cannot change on --resume: the run's plan is "
                     f"{os.path.join(args.resume, 'config.json')} (only --time-limit, "
                     f"--no-progress, --tensorboard and --wandb may be given)")
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
    if args.wandb:
      outputs.append(sinks.WandB(plan, args.wandb))
    log = sinks.log_line
  for line in start_lines(plan, resumed=args.resume is not None):
    log(line, flush=True)
  clock = Clock.starting_now(args.time_limit,
                             os.path.join(plan.out, "timing.json") if writer else None)
  processes.watch(lambda why: print(f"error: ProcessLost: {why}; {_saved(plan)}; continue "
                                    f"with --resume {plan.out}", file=sys.stderr, flush=True))
  try:
    with sinks.closing(outputs):
      run.run_plan(plan, outputs, clock, log, programs)
  except NonFinite as e:
    print(f"error: {e}", file=sys.stderr)
    return EXIT_FAILED
  except TimeLimit as e:
    log(f"time limit: {e}", flush=True)
    return EXIT_TIME_LIMIT
  except (rows.MetricsError, checkpoints.CheckpointError):
    raise
  except KeyboardInterrupt as e:  # Ctrl-C or SIGTERM, taken where nothing is half-written
    interrupts.say(_stopped(plan, type(e)))
    return EXIT_FAILED
  except Exception as e:  # noqa: BLE001 - one line, not a traceback
    if os.environ.get("NONMONO_TRACEBACK"):
      raise
    print(f"error: {_describe(e)}; {_saved(plan)}; continue with --resume {plan.out} "
          f"(NONMONO_TRACEBACK=1 shows the traceback)", file=sys.stderr, flush=True)
    return EXIT_FAILED
  log(f"done: {os.path.join(plan.out, 'metrics.csv')}", flush=True)
  return 0


def start_lines(plan: plan_lib.Plan, resumed: bool = False) -> list[str]:
  """What the run is: its task, variants, seeds, steps, env steps in all, preset, physics and
  folder; for a new run at the paper's size, that it is long and how to get a short one."""
  spec = plan.spec
  env_steps = sum(c.num_envs for c in plan.configs.values()) * spec.seeds * spec.steps
  physics = f", {plan.physics} physics" if plan.physics else ""
  if plan.contacts is not None:
    physics += f", {plan.contacts} contacts"
  across = f", {processes.count()} processes" if processes.count() > 1 else ""
  lines = [f"{plan.task}: {', '.join(plan.configs)} x {spec.seeds} seeds x {spec.steps} steps "
           f"= {_count(env_steps)} env steps ({plan.preset} preset{physics}{across}) -> "
           f"{plan.out}"]
  if plan.preset == "paper" and not resumed:
    lines.append(f"{plan.task}: the paper's size, a long run (the time it takes here is "
                 f"estimated after its first chunk); --preset quick runs the whole pipeline "
                 f"in minutes")
  return lines


def _count(n: int) -> str:
  """1,234 as 1.2K, 15,750,000 as 15.8M."""
  for size, unit in ((1e9, "G"), (1e6, "M"), (1e3, "K")):
    if n >= size:
      return f"{n / size:.3g}{unit}"
  return str(n)


def _describe(e: BaseException) -> str:
  """One line for an exception: a full disk said as such, else its type and first line."""
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
