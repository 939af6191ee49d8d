"""The experiment command shared by ``python -m experiments.<task>``: train methods, log, resume.

    python -m experiments.pointmaze --method ours hiro --preset quick --out runs/pm
    python -m experiments.antpush --method ours --seeds 5 --out runs/push     # paper preset
    python -m experiments.antpush --resume runs/push                          # after a stop
    python -m experiments.antpush --top.alpha 0 0.4 0.7 --low.batch_size 256  # any field

Methods run one after another into one folder (``nonmono_jax.io``): ``config.json``,
``metrics.csv`` (one row per method, seed and chunk) and ``checkpoints/<method>/``.

- Every value is checked before anything compiles or the folder is created: the configs'
  own ranges, ``nonmono_jax.validation`` (finite floats, int32 ints, full dotted names) and
  the memory the run needs (``jax.eval_shape`` of the trainer's init) against what is free.
- One process writes a run folder at a time (``nonmono_jax.runlock``, held for the whole run).
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
import contextlib
import dataclasses
import datetime
import errno
import math
import os
import platform
import signal
import sys
import threading
import time
import typing
from importlib import metadata

import jax
import numpy as np

import envs
from nonmono_jax import config as config_lib
from nonmono_jax import hierarchy, io, methods, runlock, train, validation

EXIT_FAILED, EXIT_BAD_INPUT, EXIT_TIME_LIMIT = 1, 2, 3
EXIT_NON_FINITE = EXIT_FAILED
# What --resume may change: how this process runs, not what the run is.
RESUME_ALLOWED = ("resume", "time_limit", "no_progress", "tensorboard")
PACKAGES = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "brax", "flax", "optax", "orbax-checkpoint",
            "numpy", "nonmono-jax")


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


def _get(obj, dotted):
  for part in dotted.split("."):
    obj = getattr(obj, part)
  return obj


def _add_field_flags(parser: argparse.ArgumentParser, example: config_lib.AgentConfig):
  group = parser.add_argument_group(
      "agent config fields (defaults: this task's preset for ours; each method's preset may "
      "differ, see nonmono_jax/methods.py)")
  for name, t in _fields(config_lib.AgentConfig):
    default = _get(example, name)
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


def _nest(flat: dict) -> dict:
  nested: dict = {}
  for dotted, value in flat.items():
    parts = dotted.split(".")
    d = nested
    for p in parts[:-1]:
      d = d.setdefault(p, {})
    d[parts[-1]] = tuple(value) if isinstance(value, list) else value
  return nested


def apply_overrides(config, overrides: dict, prefix: str = ""):
  """``dataclasses.replace`` along dotted paths: {"top": {"alpha": (...)}, "c": 5}.

  A nested config's own check names its field without the path (``lr_actor must be ...``):
  the ValueError is re-raised with the full dotted name (``low.lr_actor must be ...``).
  """
  changes = {}
  for name, value in overrides.items():
    if isinstance(value, dict):
      changes[name] = apply_overrides(getattr(config, name), value, prefix + name + ".")
    else:
      validation.check_value(prefix + name, value)
      changes[name] = value
  try:
    return dataclasses.replace(config, **changes)
  except ValueError as e:
    msg = str(e)
    raise ValueError(msg if not prefix or msg.startswith(prefix.split(".")[0] + ".")
                     else prefix + msg) from None
  except TypeError as e:  # a field that is not one (a config.json written by other code)
    raise ValueError(f"{prefix}{e}") from None


# --- the parser --------------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
  """argparse with every error on one line (no usage block): ``prog: error: message``."""

  def error(self, message):
    self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def make_parser(task: str) -> argparse.ArgumentParser:
  p = _Parser(
      prog=f"python -m experiments.{task.lower()}",
      description=f"Train methods of Kim et al. (2023) on {task}; seeds are vmapped.",
      formatter_class=argparse.ArgumentDefaultsHelpFormatter)
  p.add_argument("--method", nargs="+", default=["ours"], choices=methods.METHODS,
                 help="one or more; several run one after another into --out")
  p.add_argument("--preset", default="paper", choices=methods.PRESETS,
                 help="paper: SPEC's numbers; quick: minutes on a CPU")
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
  p.add_argument("--no-progress", action="store_true", help="no progress bar")
  p.add_argument("--tensorboard", action="store_true",
                 help="also write TensorBoard event files to OUT/tensorboard/<method>")
  _add_field_flags(p, methods.make_config("ours", task))
  return p


@dataclasses.dataclass
class Plan:
  task: str
  preset: str
  seed: int
  out: str
  spec: methods.RunSpec
  configs: dict  # method -> AgentConfig
  overrides: dict
  widen: dict = dataclasses.field(default_factory=dict)  # --envs-per-seed, --grad-steps
  trainers: dict = dataclasses.field(default_factory=dict, repr=False, compare=False)

  def trainer(self, method: str) -> train.Trainer:
    """The method's trainer, built once (the memory check and the run share it)."""
    if method not in self.trainers:
      env = envs.make(self.task, episode_length=self.spec.episode_length)
      self.trainers[method] = train.make_trainer(env, self.configs[method],
                                                 num_seeds=self.spec.seeds,
                                                 chunk_steps=self.spec.chunk)
    return self.trainers[method]


def plan_from_args(task: str, args: argparse.Namespace) -> Plan:
  """Every config built and validated; raises ValueError naming the field."""
  flat = {k[len("field:"):]: v for k, v in vars(args).items() if k.startswith("field:")}
  overrides = _nest(flat)
  envs_per_seed = getattr(args, "envs_per_seed", None)
  grad_steps = getattr(args, "grad_steps", None)
  if grad_steps is not None and envs_per_seed is None:
    raise ValueError("--grad-steps needs --envs-per-seed")
  validation.check_value("--seed", args.seed)
  configs, spec = {}, None
  for method in args.method:
    config, s = methods.make_preset(args.preset, method, task)
    if envs_per_seed is not None:
      config, s = methods.widen(config, s, envs_per_seed, grad_steps)
    configs[method] = _explained(apply_overrides, flat, config, overrides)
    spec = spec or s
  changes = {k: v for k, v in (("steps", args.steps), ("seeds", args.seeds),
                               ("chunk", args.chunk), ("checkpoint_every", args.checkpoint_every),
                               ("episode_length", args.episode_length)) if v is not None}
  if "chunk" in changes and "checkpoint_every" not in changes:
    changes["checkpoint_every"] = max(changes["chunk"], spec.checkpoint_every // changes["chunk"]
                                      * changes["chunk"])
  spec = dataclasses.replace(spec, **changes)
  configs = {m: _sized_for_run(c, spec, overrides) for m, c in configs.items()}
  check_plan(task, spec, configs)
  stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
  out = args.out if args.out is not None else os.path.join("runs", f"{task.lower()}-{stamp}")
  if not out:
    raise ValueError("--out must not be empty")
  return Plan(task=task, preset=args.preset, seed=args.seed, out=out, spec=spec,
              configs=configs, overrides=overrides,
              widen={"envs_per_seed": envs_per_seed, "grad_steps": grad_steps})


def _sized_for_run(config, spec: methods.RunSpec, overrides: dict):
  """Replay buffers that hold the whole run (``spec.steps``), as the paper's never evict;
  a buffer size given as an override wins (a smaller one is a ring)."""
  return apply_overrides(methods.size_buffers(config, spec.steps), overrides)


def _explained(fn, flat: dict, *args):
  """``fn(*args)``; a ValueError about one field that another, user-set one caused (``--c 7``
  breaking ``middle_ppo_every``) also names the user's flags it mentions."""
  try:
    return fn(*args)
  except ValueError as e:
    msg = str(e)
    subject = msg.split(" ")[0]
    mentioned = [n for n in flat if n != subject and (f" {n} " in msg or f" {n}:" in msg
                                                      or f"{n} (" in msg)]
    if mentioned:
      given = ", ".join(f"--{n} {_show(flat[n])}" for n in mentioned)
      msg += f" (from {given}: change {subject} too, or that flag)"
    raise ValueError(msg) from None


def _show(value) -> str:
  return " ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def check_plan(task: str, spec: methods.RunSpec, configs: dict) -> None:
  """The run size and every config: finite, int32, consistent; raises ValueError naming it."""
  validation.check(spec, flags=True)
  for name in ("steps", "seeds", "chunk", "checkpoint_every", "episode_length"):
    if getattr(spec, name) < 1:
      raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {getattr(spec, name)}")
  if spec.steps % spec.chunk:
    raise ValueError(f"--steps ({spec.steps}) must be a multiple of --chunk ({spec.chunk})")
  if spec.checkpoint_every % spec.chunk:
    raise ValueError(f"--checkpoint-every ({spec.checkpoint_every}) must be a multiple of "
                     f"--chunk ({spec.chunk})")
  env = envs.make(task, episode_length=spec.episode_length)
  for method, config in configs.items():
    validation.check(config)
    config.check_env(env)
    validation.check_value(f"--steps x num_envs of {method}", spec.steps * config.num_envs)
  if spec.seeds % jax.device_count():
    raise ValueError(f"--seeds ({spec.seeds}) must be a multiple of the device count "
                     f"({jax.device_count()})")


def _versions() -> dict:
  out = {}
  for name in PACKAGES:
    try:
      out[name] = metadata.version(name)
    except metadata.PackageNotFoundError:
      out[name] = None
  return out


def plan_to_json(plan: Plan) -> dict:
  return {"task": plan.task, "preset": plan.preset, "seed": plan.seed,
          "methods": list(plan.configs), "run": io.to_jsonable(plan.spec),
          "overrides": io.to_jsonable(plan.overrides), "widen": plan.widen,
          "configs": {m: io.to_jsonable(c) for m, c in plan.configs.items()},
          "versions": _versions(), "python": platform.python_version(),
          "device": str(jax.devices()[0].device_kind), "platform": jax.default_backend(),
          "device_count": jax.device_count(), "command": " ".join(sys.argv)}


def plan_from_json(payload, out: str, task: str | None = None) -> Plan:
  """The saved plan, rebuilt from the presets and the saved overrides (checked equal);
  raises ValueError naming ``OUT/config.json`` and what is wrong with it."""
  path = os.path.join(out, "config.json")
  try:
    _check_payload(payload)
    if task is not None and payload["task"] != task:
      raise ValueError(f"it is a {payload['task']} run, not {task}: resume it with python -m "
                       f"experiments.{payload['task'].lower()}")
    args = argparse.Namespace(method=payload["methods"], preset=payload["preset"],
                              seeds=None, steps=None, chunk=None, checkpoint_every=None,
                              episode_length=None, seed=payload["seed"], out=out,
                              **payload.get("widen", {}))
    plan = plan_from_args(payload["task"], args)
    plan.spec = methods.RunSpec(**payload["run"])
    plan.configs = {m: _sized_for_run(c, plan.spec, _lists_to_tuples(payload["overrides"]))
                    for m, c in plan.configs.items()}
    plan.overrides = payload["overrides"]
    check_plan(plan.task, plan.spec, plan.configs)
  except (ValueError, TypeError, KeyError) as e:
    raise ValueError(f"{path}: {e}") from None
  for m, c in plan.configs.items():
    if io.to_jsonable(c) != payload["configs"].get(m):
      raise ValueError(f"{path}: the saved config of {m} no longer matches its preset + "
                       f"overrides (the code changed since the run started)")
  return plan


def _check_payload(payload) -> None:
  """The keys and types ``config.json`` must have, before anything is read from it."""
  if not isinstance(payload, dict):
    raise ValueError(f"expected a JSON object, got a {type(payload).__name__}")
  for key, kind in (("task", str), ("preset", str), ("seed", int), ("methods", list),
                    ("run", dict), ("overrides", dict), ("configs", dict)):
    if key not in payload:
      raise ValueError(f"the key {key!r} is missing")
    if not isinstance(payload[key], kind):
      raise ValueError(f"{key} must be a {kind.__name__}, got {payload[key]!r}")
  if payload["task"] not in envs.NAMES:
    raise ValueError(f"task {payload['task']!r} is not one of {', '.join(envs.NAMES)}")
  fields = {f.name for f in dataclasses.fields(methods.RunSpec)}
  if set(payload["run"]) != fields:
    raise ValueError(f"run must have exactly the keys {', '.join(sorted(fields))}")
  for key, value in payload["run"].items():
    if not isinstance(value, int) or isinstance(value, bool):
      raise ValueError(f"run.{key} must be an integer, got {value!r}")
  if not isinstance(payload.get("widen", {}), dict):
    raise ValueError("widen must be an object")


def _lists_to_tuples(d):
  return {k: (_lists_to_tuples(v) if isinstance(v, dict) else
              tuple(v) if isinstance(v, list) else v) for k, v in d.items()}


# --- the run -----------------------------------------------------------------------------------

class NonFinite(RuntimeError):
  pass


class TimeLimit(RuntimeError):
  pass


@dataclasses.dataclass
class Clock:
  """Wall-clock budget of one process: may the next chunk start?

  A chunk's duration is estimated by the latest one of the same method; a method's first
  chunk in a process (which compiles, or loads the compiled program from the cache) by the
  longest first chunk seen so far in this run, kept in ``OUT/timing.json`` so that a resumed
  process knows it too (0 before any).
  """

  deadline: float | None = None  # time.monotonic() value
  first_chunk_s: float = 0.0
  path: str | None = None  # timing.json of the run
  progressed: bool = False  # has this process run a chunk? (the first always runs)

  @classmethod
  def starting_now(cls, limit_s: float | None, path: str | None = None, log=print) -> "Clock":
    first = 0.0
    if path and os.path.exists(path):
      try:
        first = float(io.read_json(path)["first_chunk_s"])
        if not (math.isfinite(first) and first >= 0):
          raise ValueError(first)
      except (OSError, ValueError, KeyError, TypeError):
        log(f"{path} is unreadable: ignored (it only estimates the first chunk's time)")
        first = 0.0
    return cls(None if limit_s is None else time.monotonic() + limit_s, first, path)

  def saw_first_chunk(self, seconds: float) -> None:
    if seconds > self.first_chunk_s:
      self.first_chunk_s = seconds
      if self.path:
        io.write_json(self.path, {"first_chunk_s": seconds})

  def allows(self, chunk_s: float | None) -> bool:
    if self.deadline is None:
      return True
    estimate = self.first_chunk_s if chunk_s is None else chunk_s
    return time.monotonic() + estimate <= self.deadline


def _progress(total, initial, desc, enabled):
  if not enabled:
    return None
  from tqdm import tqdm
  return tqdm(total=total, initial=initial, desc=desc, unit="step", dynamic_ncols=True,
              smoothing=0.1)


def _tensorboard_writer(plan: Plan, method: str):
  from tensorboardX import SummaryWriter  # a dependency of brax
  return SummaryWriter(os.path.join(plan.out, "tensorboard", method))


def _write_scalars(writer, rows):
  """Means over seeds of every numeric column, and S_E per seed."""
  step = rows[0]["env_step"]
  for col in io.COLUMNS[4:]:
    values = [r[col] for r in rows if r[col] != ""]
    if values:
      writer.add_scalar(col, sum(values) / len(values), step)
  for r in rows:
    if r["eval_success"] != "":
      writer.add_scalar(f"eval_success/seed{r['seed']}", r["eval_success"], step)
  writer.flush()


def train_method(plan: Plan, method: str, metrics_file: io.MetricsFile, progress: bool,
                 log=print, tensorboard: bool = False, clock: Clock | None = None) -> None:
  spec, config = plan.spec, plan.configs[method]
  trainer = plan.trainer(method)
  ckpts = io.Checkpoints(os.path.join(plan.out, "checkpoints", method))
  start, states = ckpts.restore_newest(trainer.init(jax.random.PRNGKey(plan.seed)), log)
  start = start or 0
  if start:
    log(f"{method}: resumed from step {start}")
  metrics_file.truncate(method, start * config.num_envs)
  if start >= spec.steps:
    ckpts.close()
    return
  bar = _progress(spec.steps, start, f"{plan.task} {method}", progress)
  writer = _tensorboard_writer(plan, method) if tensorboard else None
  clock = clock or Clock()
  t_start, steps_done = None, 0  # the rate leaves out the first chunk (it compiles)
  chunk_s = None  # the latest chunk's wall time (None before the first)
  try:
    for t0 in range(start, spec.steps, spec.chunk):
      # At least one chunk per process: a limit shorter than start-up + a chunk still advances.
      if not clock.allows(chunk_s) and clock.progressed:
        raise TimeLimit(_stop_for_time(plan, method, ckpts, t0, states))
      t_chunk = time.monotonic()
      states, metrics = trainer.chunk(states, t0)
      t_end = t0 + spec.chunk
      bad = io.first_non_finite(states, metrics)
      if bad is not None:
        last = ckpts.latest_step()
        raise NonFinite(f"{method}: NaN or Inf in {bad[1]} of seed {bad[0]} within steps "
                        f"{t0}-{t_end}; " + (f"the last good checkpoint is step {last}"
                                             if last is not None else
                                             "no checkpoint was saved before it"))
      rows = io.chunk_rows(plan.task, method, t_end * config.num_envs, states, metrics,
                           spec.episode_length, t_end >= config.first_eval_steps)
      metrics_file.append(rows)
      if writer is not None:
        _write_scalars(writer, rows)
      if t_end % spec.checkpoint_every == 0 or t_end == spec.steps:
        ckpts.save(t_end, states)
      clock.progressed = True
      if _INTERRUPTED.is_set():  # a Ctrl-C that JAX swallowed (raised in a GC callback)
        raise KeyboardInterrupt
      chunk_s = time.monotonic() - t_chunk  # io.first_non_finite above waited for the chunk
      if t_start is None:
        clock.saw_first_chunk(chunk_s)
        t_start, rate = time.perf_counter(), float("nan")
      else:
        steps_done += spec.chunk
        rate = steps_done * spec.seeds * config.num_envs / (time.perf_counter() - t_start)
      _show_progress(bar, log, method, t_end, spec, rows, rate)
  finally:
    if bar:
      bar.close()
    if writer is not None:
      writer.close()
    ckpts.close()


def _stop_for_time(plan: Plan, method: str, ckpts: io.Checkpoints, t0: int, states) -> str:
  """Checkpoints step ``t0`` if it is not yet; the time-limit message (saying what is saved)."""
  if t0 and ckpts.latest_step() != t0:
    ckpts.save(t0, states)
  saved = "checkpointed" if t0 else "nothing of it run yet"
  return (f"{method}: stopped at step {t0} of {plan.spec.steps} for the time limit ({saved}); "
          f"continue with --resume {plan.out}")


def _show_progress(bar, log, method, t_end, spec, rows, rate) -> None:
  s_e = sum(r["eval_success"] or 0.0 for r in rows) / len(rows)
  shares = {m: sum(r[f"steps_{m}"] for r in rows) for m in hierarchy.MODES}
  total = max(sum(shares.values()), 1)
  status = (f"S_E {s_e:.2f} | " + " ".join(f"{m} {shares[m] / total:.0%}"
                                            for m in hierarchy.MODES) + f" | {rate:.0f} env/s")
  if bar:
    bar.set_postfix_str(status, refresh=False)
    bar.update(spec.chunk)
  else:
    log(f"{method} step {t_end}/{spec.steps}: {status}")


# --- the command: checks, the run folder, the run ----------------------------------------------

class BadFolder(ValueError):
  """A run folder that cannot be created or continued (exit code 2)."""


def main(task: str, argv=None) -> int:
  parser = make_parser(task)
  args = parser.parse_args(argv)
  try:
    plan = _plan(task, args, argv)
    _check_memory(plan)
  except ValueError as e:
    parser.error(str(e))
  try:
    with _run_folder(plan, resume=args.resume is not None):
      return _run(plan, args)
  except (BadFolder, runlock.Locked, io.MetricsError, io.CheckpointError) as e:
    parser.error(str(e))


def _plan(task: str, args: argparse.Namespace, argv) -> Plan:
  """The checked plan of a new run or of ``--resume``; raises ValueError with one line."""
  limit = args.time_limit
  if limit is not None and not (math.isfinite(limit) and limit > 0):
    raise ValueError(f"--time-limit must be a positive number of seconds, got {limit}")
  if args.resume is None:
    plan = plan_from_args(task, args)
    if os.path.lexists(plan.out):
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
  return plan_from_json(read_config(args.resume), args.resume, task=task)


def _given_dests(task: str, argv) -> set[str]:
  """The destinations of the options written on the command line (defaults left out)."""
  p = make_parser(task)
  for action in p._actions:
    action.default = argparse.SUPPRESS
  return set(vars(p.parse_args(argv)))


def read_config(out: str):
  """``OUT/config.json`` as JSON; raises ValueError naming the file."""
  path = os.path.join(out, "config.json")
  if not os.path.isfile(path):
    raise ValueError(f"{out}: no config.json there (not a run folder)")
  try:
    return io.read_json(path)
  except (OSError, UnicodeDecodeError) as e:
    raise ValueError(f"{path}: cannot be read ({e})") from None
  except ValueError as e:
    raise ValueError(f"{path}: not valid JSON ({e})") from None


def _available_bytes() -> int | None:
  """Memory the run may use: the devices' limit on an accelerator, else MemAvailable."""
  if jax.default_backend() != "cpu":
    stats = jax.devices()[0].memory_stats() or {}
    limit = stats.get("bytes_limit")
    return None if limit is None else limit * jax.device_count()
  try:
    with open("/proc/meminfo") as f:
      for line in f:
        if line.startswith("MemAvailable:"):
          return int(line.split()[1]) * 1024
  except OSError:
    pass
  try:
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
  except (ValueError, OSError):
    return None


def state_bytes(plan: Plan, method: str) -> int:
  """Bytes of the method's train state for all seeds (buffers, networks, envs): the shapes of
  ``trainer.init`` from ``jax.eval_shape``, so nothing is allocated."""
  shapes = jax.eval_shape(plan.trainer(method).init, jax.random.PRNGKey(0))
  return sum(int(np.prod(x.shape, dtype=np.float64)) * x.dtype.itemsize
             for x in jax.tree.leaves(shapes))


EVAL_RECORD_BYTES = 64  # an evaluation step's record (position, goal, blocks, success), about


def _check_memory(plan: Plan) -> None:
  """Refuses a run whose train state plus its evaluation's per-step records exceed the memory
  available (methods run one after another: each is checked on its own)."""
  have = _available_bytes()
  spec = plan.spec
  for method, config in plan.configs.items():
    state = state_bytes(plan, method)
    evals = (spec.seeds * config.num_envs * config.eval_episodes * spec.episode_length
             * EVAL_RECORD_BYTES)
    if have is not None and state + evals > have:
      raise ValueError(f"{method} for {spec.seeds} seeds needs {(state + evals) / 2**30:.1f} "
                       f"GiB (train state with its replay buffers {state / 2**30:.1f}, "
                       f"evaluation episodes {evals / 2**30:.1f}), more than the "
                       f"{have / 2**30:.1f} GiB available: use fewer --seeds, smaller "
                       f"buffers (--low.buffer_size, --middle.buffer_size) or shorter episodes")


@contextlib.contextmanager
def _run_folder(plan: Plan, resume: bool):
  """Creates (a new run) and locks the run folder for the block; writes ``config.json``."""
  try:
    os.makedirs(plan.out, exist_ok=resume)
  except FileExistsError:
    pass  # an empty folder given as --out: checked in _plan
  except OSError as e:
    raise BadFolder(f"--out {plan.out}: cannot create the folder ({e.strerror})") from None
  with contextlib.ExitStack() as stack:
    try:
      stack.enter_context(runlock.hold(plan.out))
    except OSError as e:
      raise BadFolder(f"{plan.out}: cannot lock the run folder ({e.strerror})") from None
    _check_folder(plan, resume)
    yield


def _check_folder(plan: Plan, resume: bool) -> None:
  """With the lock held: a new run's folder is still empty; a resumed one is complete."""
  if not resume:
    if set(os.listdir(plan.out)) - {runlock.NAME}:
      raise BadFolder(f"--out {plan.out} was filled by another process meanwhile")
    try:
      io.write_json(os.path.join(plan.out, "config.json"), plan_to_json(plan))
    except OSError as e:
      raise BadFolder(f"{plan.out}/config.json: cannot be written ({e.strerror})") from None
    return
  metrics = os.path.join(plan.out, "metrics.csv")
  ckpts = os.path.join(plan.out, "checkpoints")
  if not os.path.exists(metrics) and os.path.isdir(ckpts) and os.listdir(ckpts):
    raise BadFolder(f"{metrics} is missing while checkpoints exist: the rows before them "
                    f"would be lost (put it back, or start a new run)")
  if os.path.exists(metrics):
    io.good_lines(metrics)  # raises MetricsError naming the file


def _run(plan: Plan, args: argparse.Namespace) -> int:
  """Trains every method of the plan; the exit code (0, 1 failed, 3 time limit)."""
  metrics_file = io.MetricsFile(os.path.join(plan.out, "metrics.csv"))
  print(f"{plan.task}: {', '.join(plan.configs)} x {plan.spec.seeds} seeds x {plan.spec.steps} "
        f"steps ({plan.preset}) -> {plan.out}", flush=True)
  clock = Clock.starting_now(args.time_limit, os.path.join(plan.out, "timing.json"))
  try:
    with _remembering_ctrl_c():
      for method in plan.configs:
        train_method(plan, method, metrics_file, progress=not args.no_progress,
                     tensorboard=args.tensorboard, clock=clock)
  except NonFinite as e:
    print(f"error: {e}", file=sys.stderr)
    return EXIT_FAILED
  except TimeLimit as e:
    print(f"time limit: {e}", flush=True)
    return EXIT_TIME_LIMIT
  except (io.MetricsError, io.CheckpointError):
    raise
  except (Exception, KeyboardInterrupt) as e:  # noqa: BLE001 - one line, not a traceback
    if os.environ.get("NONMONO_TRACEBACK"):
      raise
    print(f"error: {_describe(e)}; {_saved(plan)}; continue with --resume {plan.out} "
          f"(NONMONO_TRACEBACK=1 shows the traceback)", file=sys.stderr, flush=True)
    return EXIT_FAILED
  print(f"done: {os.path.join(plan.out, 'metrics.csv')}", flush=True)
  return 0


_INTERRUPTED = threading.Event()


@contextlib.contextmanager
def _remembering_ctrl_c():
  """SIGINT raises KeyboardInterrupt as usual and is also remembered: one that lands in a
  callback that swallows exceptions (JAX's garbage-collection hook) stops the run at the end
  of the chunk instead of being lost."""
  if threading.current_thread() is not threading.main_thread():
    yield
    return

  def handler(signum, frame):
    _INTERRUPTED.set()
    raise KeyboardInterrupt

  _INTERRUPTED.clear()
  previous = signal.signal(signal.SIGINT, handler)
  try:
    yield
  finally:
    signal.signal(signal.SIGINT, previous)


def _describe(e: BaseException) -> str:
  """One line for an exception: a full disk said as such, else its type and first line."""
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


def _saved(plan: Plan) -> str:
  """Each method's last complete checkpoint, as the folder holds them now."""
  parts = []
  for method in plan.configs:
    d = os.path.join(plan.out, "checkpoints", method)
    steps = [int(n) for n in (os.listdir(d) if os.path.isdir(d) else []) if n.isdigit()
             and os.path.exists(os.path.join(d, n, "commit_success.txt"))]
    parts.append(f"{method} step {max(steps)}" if steps else f"{method} none")
  return "last good checkpoints: " + ", ".join(parts)
