"""The experiment command shared by ``python -m experiments.<task>``: train methods, log, resume.

    python -m experiments.pointmaze --method ours hiro --preset quick --out runs/pm
    python -m experiments.antpush --method ours --seeds 5 --out runs/push     # paper preset
    python -m experiments.antpush --resume runs/push                          # after a stop
    python -m experiments.antpush --top.alpha 0 0.4 0.7 --low.batch_size 256  # any field

Methods run one after another into one folder (``nonmono_jax.io``): ``config.json``,
``metrics.csv`` (one row per method, seed and chunk) and ``checkpoints/<method>/``. Every
value is checked before anything compiles or is written: a bad one prints one line naming the
field and exits with code 2. A NaN or Inf in a learner stops the run (exit code 1) with the
step, seed and level, after the last good checkpoint.
"""

from __future__ import annotations

import argparse
import collections.abc
import dataclasses
import datetime
import os
import platform
import sys
import time
import typing
from importlib import metadata

import jax

import envs
from nonmono_jax import config as config_lib
from nonmono_jax import hierarchy, io, methods, train

EXIT_NON_FINITE, EXIT_TIME_LIMIT = 1, 3
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


def apply_overrides(config, overrides: dict):
  """``dataclasses.replace`` along dotted paths: {"top": {"alpha": (...)}, "c": 5}."""
  changes = {}
  for name, value in overrides.items():
    if isinstance(value, dict):
      changes[name] = apply_overrides(getattr(config, name), value)
    else:
      changes[name] = value
  return dataclasses.replace(config, **changes)


# --- the parser --------------------------------------------------------------------------------

def make_parser(task: str) -> argparse.ArgumentParser:
  p = argparse.ArgumentParser(
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


def plan_from_args(task: str, args: argparse.Namespace) -> Plan:
  """Every config built and validated; raises ValueError naming the field."""
  overrides = _nest({k[len("field:"):]: v for k, v in vars(args).items()
                     if k.startswith("field:")})
  envs_per_seed = getattr(args, "envs_per_seed", None)
  grad_steps = getattr(args, "grad_steps", None)
  if grad_steps is not None and envs_per_seed is None:
    raise ValueError("--grad-steps needs --envs-per-seed")
  configs, spec = {}, None
  for method in args.method:
    config, s = methods.make_preset(args.preset, method, task)
    if envs_per_seed is not None:
      config, s = methods.widen(config, s, envs_per_seed, grad_steps)
    configs[method] = apply_overrides(config, overrides)
    spec = spec or s
  changes = {k: v for k, v in (("steps", args.steps), ("seeds", args.seeds),
                               ("chunk", args.chunk), ("checkpoint_every", args.checkpoint_every),
                               ("episode_length", args.episode_length)) if v is not None}
  if "chunk" in changes and "checkpoint_every" not in changes:
    changes["checkpoint_every"] = max(changes["chunk"], spec.checkpoint_every // changes["chunk"]
                                      * changes["chunk"])
  spec = dataclasses.replace(spec, **changes)
  for name in ("steps", "seeds", "chunk", "checkpoint_every", "episode_length"):
    if getattr(spec, name) < 1:
      raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {getattr(spec, name)}")
  if spec.steps % spec.chunk:
    raise ValueError(f"--steps ({spec.steps}) must be a multiple of --chunk ({spec.chunk})")
  if spec.checkpoint_every % spec.chunk:
    raise ValueError(f"--checkpoint-every ({spec.checkpoint_every}) must be a multiple of "
                     f"--chunk ({spec.chunk})")
  env = envs.make(task, episode_length=spec.episode_length)
  for config in configs.values():
    config.check_env(env)
  if spec.seeds % jax.device_count():
    raise ValueError(f"--seeds ({spec.seeds}) must be a multiple of the device count "
                     f"({jax.device_count()})")
  stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
  out = args.out or os.path.join("runs", f"{task.lower()}-{stamp}")
  return Plan(task=task, preset=args.preset, seed=args.seed, out=out, spec=spec,
              configs=configs, overrides=overrides,
              widen={"envs_per_seed": envs_per_seed, "grad_steps": grad_steps})


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


def plan_from_json(payload: dict, out: str) -> Plan:
  """The saved plan, rebuilt from the presets and the saved overrides (checked equal)."""
  task = payload["task"]
  args = argparse.Namespace(method=payload["methods"], preset=payload["preset"],
                            seeds=None, steps=None, chunk=None, checkpoint_every=None,
                            episode_length=None, seed=payload["seed"], out=out,
                            **payload.get("widen", {}))
  plan = plan_from_args(task, args)
  plan.spec = methods.RunSpec(**payload["run"])
  plan.configs = {m: apply_overrides(c, _lists_to_tuples(payload["overrides"]))
                  for m, c in plan.configs.items()}
  plan.overrides = payload["overrides"]
  for m, c in plan.configs.items():
    if io.to_jsonable(c) != payload["configs"][m]:
      raise ValueError(f"the saved config of {m} no longer matches its preset + overrides "
                       f"(the code changed since the run started)")
  return plan


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

  @classmethod
  def starting_now(cls, limit_s: float | None, path: str | None = None) -> "Clock":
    first = io.read_json(path)["first_chunk_s"] if path and os.path.exists(path) else 0.0
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
  env = envs.make(plan.task, episode_length=spec.episode_length)
  trainer = train.make_trainer(env, config, num_seeds=spec.seeds, chunk_steps=spec.chunk)
  ckpts = io.Checkpoints(os.path.join(plan.out, "checkpoints", method))
  start = ckpts.latest_step() or 0
  states = trainer.init(jax.random.PRNGKey(plan.seed))
  if start:
    states = ckpts.restore(start, states)
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
  for t0 in range(start, spec.steps, spec.chunk):
    if not clock.allows(chunk_s):
      if t0 > start and ckpts.latest_step() != t0:
        ckpts.save(t0, states)
      ckpts.close()
      if bar:
        bar.close()
      if writer is not None:
        writer.close()
      raise TimeLimit(f"{method}: stopped at step {t0} of {spec.steps} for the time limit "
                      f"(checkpointed); continue with --resume {plan.out}")
    t_chunk = time.monotonic()
    states, metrics = trainer.chunk(states, t0)
    t_end = t0 + spec.chunk
    bad = io.first_non_finite(states, metrics)
    if bad is not None:
      if bar:
        bar.close()
      last = ckpts.latest_step()
      ckpts.close()
      raise NonFinite(f"{method}: NaN or Inf in {bad[1]} of seed {bad[0]} within steps "
                      f"{t0}-{t_end}; the last good checkpoint is step {last}")
    evaluated = t_end >= config.first_eval_steps
    rows = io.chunk_rows(plan.task, method, t_end * config.num_envs, states, metrics,
                         spec.episode_length, evaluated)
    metrics_file.append(rows)
    if writer is not None:
      _write_scalars(writer, rows)
    if t_end % spec.checkpoint_every == 0 or t_end == spec.steps:
      ckpts.save(t_end, states)
    chunk_s = time.monotonic() - t_chunk  # io.first_non_finite above waited for the chunk
    if t_start is None:
      clock.saw_first_chunk(chunk_s)
      t_start, rate = time.perf_counter(), float("nan")
    else:
      steps_done += spec.chunk
      rate = steps_done * spec.seeds * config.num_envs / (time.perf_counter() - t_start)
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
  if bar:
    bar.close()
  if writer is not None:
    writer.close()
  ckpts.close()


def main(task: str, argv=None) -> int:
  parser = make_parser(task)
  args = parser.parse_args(argv)
  try:
    if args.resume:
      path = os.path.join(args.resume, "config.json")
      if not os.path.exists(path):
        parser.error(f"--resume {args.resume}: no config.json there")
      plan = plan_from_json(io.read_json(path), args.resume)
    else:
      plan = plan_from_args(task, args)
      if os.path.exists(plan.out) and os.listdir(plan.out):
        parser.error(f"--out {plan.out} exists and is not empty (use --resume {plan.out} to "
                     f"continue it, or another --out)")
  except ValueError as e:
    parser.error(str(e))
  os.makedirs(plan.out, exist_ok=True)
  if not args.resume:
    io.write_json(os.path.join(plan.out, "config.json"), plan_to_json(plan))
  metrics_file = io.MetricsFile(os.path.join(plan.out, "metrics.csv"))
  print(f"{plan.task}: {', '.join(plan.configs)} x {plan.spec.seeds} seeds x {plan.spec.steps} "
        f"steps ({plan.preset}) -> {plan.out}", flush=True)
  clock = Clock.starting_now(args.time_limit, os.path.join(plan.out, "timing.json"))
  try:
    for method in plan.configs:
      train_method(plan, method, metrics_file, progress=not args.no_progress,
                   tensorboard=args.tensorboard, clock=clock)
  except NonFinite as e:
    print(f"error: {e}", file=sys.stderr)
    return EXIT_NON_FINITE
  except TimeLimit as e:
    print(f"time limit: {e}", flush=True)
    return EXIT_TIME_LIMIT
  print(f"done: {os.path.join(plan.out, 'metrics.csv')}", flush=True)
  return 0
