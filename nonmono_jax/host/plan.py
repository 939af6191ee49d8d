"""What a run is: its task, methods, configs and size, made new or loaded from ``config.json``.

    plan = plan_lib.new_run("PointMaze", ["ours", "hiro"], preset="quick", out="runs/pm",
                            overrides={"top.alpha": (0, 0.4, 0.7)}, run={"steps": 6000})
    plan = plan_lib.load_run("runs/pm")     # config.json is the source of truth
    plan.warnings                           # where it differs from today's presets
    plan = plan_lib.new_run("PointMaze", ["ours"], sweep={"top.alpha": [(0, .4, .7), (0, .2, .35)]})
    plan.groups()                           # [["ours+top.alpha=0,0.4,0.7", ...]]: one program

A plan's configs are its variants, by name: a method (``ours``), or a method with sweep values
(``ours+top.alpha=0,0.2,0.35``; ``variants`` keeps each one's method and values). Variants
whose configs share a static key (``lanes.static_key``) are one group: one program of lanes.

A new run is built from the presets (``methods.build_config``) and dotted overrides; a saved
one is read back from its ``config.json`` (``folder.py``, ``config.config_from_dict``), not
rebuilt: a preset default
changed since the run started is a warning, and the run resumes, plots and renders as it
was. A plan is data: its trainers are built on the run side (``programs.Programs``, which
also checks the memory). Every value is checked before anything compiles (``check_plan``);
errors are ValueErrors of one line naming the field (or ``config.json``).
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import itertools
import os

import jax

import envs
from envs.physics import PHYSICS
from envs import contacts as contacts_lib
from nonmono_jax.core import lanes, validation
from nonmono_jax.core.config import AgentConfig, config_from_dict, differences, flatten, get
from nonmono_jax.core.config import missing_fields, override
from nonmono_jax.host import folder, methods, provenance

RUN_FIELDS = methods.RUN_FIELDS


@dataclasses.dataclass
class Plan:
  task: str
  preset: str
  seed: int
  out: str
  spec: methods.RunSpec
  configs: dict  # variant name -> AgentConfig
  overrides: dict  # dotted paths given on top of the presets
  widen: dict = dataclasses.field(default_factory=dict)  # envs_per_seed, grad_steps
  warnings: list = dataclasses.field(default_factory=list)  # a loaded run against today's code
  # a swept variant's name -> {"method": ..., "overrides": {path: value}} (methods: absent)
  variants: dict = dataclasses.field(default_factory=dict)
  # variants with one static key run as one program; False for runs from before (config.json
  # without "grouped"), whose methods ran one after another and resume so
  grouped: bool = True
  # the ant's physics ("c" or "mjx", envs.ant_maze); None for the point robot (pure JAX). Runs
  # from before the choice (config.json without "physics") ran on MJX and resume on it.
  physics: str | None = None
  # the ant's contact settings ("mujoco3" or "mujoco2", envs.contacts); None for the point robot.
  # Runs from before the choice (config.json without "contacts") ran on "mujoco3" and resume so.
  contacts: str | None = None

  def env(self):
    """The run's env: its task, episode length, physics and contact settings."""
    return make_env(self.task, self.spec.episode_length, self.physics, self.contacts)

  def groups(self) -> list[list[str]]:
    """The variants by program, in plan order: those with one static key share a trainer."""
    if not self.grouped:
      return [[name] for name in self.configs]
    by_key: dict = {}  # static key -> its variants (dicts keep the plan's order)
    for name, config in self.configs.items():
      by_key.setdefault(lanes.static_key(config), []).append(name)
    return list(by_key.values())


# --- a new run ----------------------------------------------------------------------------------

def new_run(task: str, method_names, preset: str = "paper", out: str | None = None,
            seed: int = 0, overrides: dict | None = None, run: dict | None = None,
            envs_per_seed: int | None = None, grad_steps: int | None = None,
            sweep: dict | None = None, physics: str | None = None,
            contacts: str | None = None) -> Plan:
  """The checked plan of a new run: the presets of ``method_names`` on ``task``, widened
  (``methods.widen_layer``), with the dotted ``overrides`` and the run size changes ``run``
  (``steps``, ``seeds``, ``chunk``, ``checkpoint_every``, ``episode_length``); replay buffers
  sized for the run unless an override gives a size. ``sweep`` (dotted path -> list of
  values; several paths: their grid) makes each method one variant per value. ``physics``:
  the ant's, ``c``, ``mjx`` or ``auto`` (None: ``auto``); ``contacts``: the ant's contact
  settings (``envs.contacts``; None: ``envs.contacts.RUN_DEFAULT``). Raises ValueError naming the
  field."""
  physics = run_physics(task, physics)
  contacts = run_contacts(task, contacts)
  overrides = flatten(overrides or {})
  if grad_steps is not None and envs_per_seed is None:
    raise ValueError("--grad-steps needs --envs-per-seed")
  validation.check_value("--seed", seed)
  widen = {"envs_per_seed": envs_per_seed, "grad_steps": grad_steps}

  def build(v):
    return methods.build_config(preset, v["method"], task, {**overrides, **v["overrides"]}, run,
                                widen)

  points = sweep_variants(method_names, sweep or {})
  built = {name: build(v) for name, v in points.items()}
  variants = _read_only(points, {name: c for name, (c, _) in built.items()}, sweep or {})
  # a variant that keeps every swept value is its grid point, built already; one that drops
  # values its method does not read (HIRO in a sweep of top.alpha) is built without them
  built = {name: built[name] if name in built else build(v) for name, v in variants.items()}
  spec = next(iter(built.values()))[1]
  configs = {name: c for name, (c, _) in built.items()}
  check_plan(task, spec, configs)
  stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
  out = out if out is not None else os.path.join("runs", f"{task.lower()}-{stamp}")
  if not out:
    raise ValueError("--out must not be empty")
  return Plan(task=task, preset=preset, seed=seed, out=out, spec=spec, configs=configs,
              overrides=overrides, widen=widen,
              variants={n: v for n, v in variants.items() if v["overrides"]}, physics=physics,
              contacts=contacts)


def run_physics(task: str, physics: str | None) -> str | None:
  """The physics a new run of ``task`` records: ``c`` or ``mjx`` for the ant, where ``auto``
  and None are resolved, here alone: MuJoCo C on a CPU backend (10-25x MJX there), MJX on an
  accelerator; None for the point robot, which has no choice."""
  if not envs.has_physics(task):
    if physics not in (None, "auto"):
      raise ValueError(f"--physics: {task} has no physics choice (the point robot is pure JAX)")
    return None
  if physics not in (None, *PHYSICS):
    raise ValueError(f"--physics must be one of {', '.join(PHYSICS)}, got {physics!r}")
  if physics in (None, "auto"):
    return "c" if jax.default_backend() == "cpu" else "mjx"
  return physics


def run_contacts(task: str, contacts: str | None) -> str | None:
  """The contact settings a new run of ``task`` records: for the ant ``contacts`` (None:
  ``envs.contacts.RUN_DEFAULT``, the paper's MuJoCo 2.0 as near as it goes), None for the
  point robot, which has no choice."""
  if not envs.has_physics(task):
    if contacts is not None:
      raise ValueError(f"--contacts: {task} has no contact settings (the point robot is pure "
                       "JAX)")
    return None
  if contacts is None:
    return contacts_lib.RUN_DEFAULT
  if contacts not in contacts_lib.CONTACTS:
    raise ValueError(f"--contacts must be one of {', '.join(contacts_lib.CONTACTS)}, got "
                     f"{contacts!r}")
  return contacts


@functools.lru_cache(maxsize=8)
def make_env(task: str, episode_length: int, physics: str | None = None,
             contacts: str | None = None):
  """``envs.make`` of a run's task: the ant with its ``physics`` (``run_physics``: None and
  ``auto`` resolved) and ``contacts`` (None: the env's default). One env per process for each
  choice (an env is pure functions; its C physics keeps no state between calls), so that a
  trainer built again for it reuses its programs (``train._programs``)."""
  extra = {}
  if envs.has_physics(task):
    extra["physics"] = run_physics(task, physics)
  if contacts is not None:
    extra["contacts"] = contacts
  return envs.make(task, episode_length=episode_length, **extra)


def sweep_variants(method_names, sweep: dict) -> dict:
  """Variant name -> {"method", "overrides"}: each method once per point of the sweep's grid,
  named ``method+path=value+...`` (a tuple's values joined by commas)."""
  paths = list(sweep)
  for path in paths:
    if not isinstance(sweep[path], (list, tuple)) or not sweep[path]:
      raise ValueError(f"--sweep {path} needs at least one value")
  out = {}
  for method in method_names:
    for point in itertools.product(*(sweep[p] for p in paths)):
      values = dict(zip(paths, point))
      out[_variant_name(method, values)] = {"method": method, "overrides": values}
  return out


def _read_only(variants: dict, configs: dict, sweep: dict) -> dict:
  """``variants`` without the swept paths their method does not read (``AgentConfig.reads``):
  HIRO in a sweep of top.alpha runs once, named ``hiro``, not once per value; a swept path
  that no method reads is a ValueError."""
  for path in sweep:
    if not any(c.reads(path) for c in configs.values()):
      methods_ = sorted({v["method"] for v in variants.values()})
      raise ValueError(f"--sweep {path}: not read by {', '.join(methods_)} (every lane would "
                       f"be the same)")
  out = {}
  for name, v in variants.items():
    kept = {p: x for p, x in v["overrides"].items() if configs[name].reads(p)}
    out.setdefault(_variant_name(v["method"], kept), {"method": v["method"], "overrides": kept})
  return out


def _variant_name(method: str, values: dict) -> str:
  return "+".join([method] + [f"{p}={_named(v)}" for p, v in values.items()])


def _named(value) -> str:
  if isinstance(value, (list, tuple)):
    return ",".join(map(_named, value))
  return f"{value:g}" if isinstance(value, float) else str(value)


# --- checks before anything compiles -------------------------------------------------------------

def check_plan(task: str, spec: methods.RunSpec, configs: dict) -> None:
  """The run size and every config: finite, int32, consistent; raises ValueError naming it."""
  validation.check(spec, flags=True)
  for name in RUN_FIELDS:
    if getattr(spec, name) < 1:
      raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {getattr(spec, name)}")
  if spec.steps % spec.chunk:
    raise ValueError(f"--steps ({spec.steps}) must be a multiple of --chunk ({spec.chunk})")
  if spec.checkpoint_every % spec.chunk:
    raise ValueError(f"--checkpoint-every ({spec.checkpoint_every}) must be a multiple of "
                     f"--chunk ({spec.chunk})")
  for method, config in configs.items():
    validation.check(config)
    config.check_env(spec.episode_length)
    validation.check_value(f"--steps x num_envs of {method}", spec.steps * config.num_envs)
  if spec.seeds % jax.device_count():
    across = (f": {jax.process_count()} processes x {jax.local_device_count()}"
              if jax.process_count() > 1 else "")
    raise ValueError(f"--seeds ({spec.seeds}) must be a multiple of the device count "
                     f"({jax.device_count()}{across}; see --cpu-devices)")


def load_run(out: str, task: str | None = None) -> Plan:
  """The run in folder ``out``, from its ``config.json`` (checked; ``task``: it must be one);
  ``plan.warnings`` says where it differs from today's presets. Raises ValueError naming
  ``OUT/config.json`` and what is wrong with it."""
  return from_json(folder.read_config(out), out, task)


def from_json(payload, out: str, task: str | None = None) -> Plan:
  """The plan ``config.json`` holds (see ``load_run``)."""
  path = os.path.join(out, "config.json")
  try:
    folder.check_payload(payload)
    if task is not None and payload["task"] != task:
      raise ValueError(f"it is a {payload['task']} run, not {task}: resume it with python -m "
                       f"experiments.{payload['task'].lower()}")
    spec = methods.RunSpec(**payload["run"])
    overrides = flatten(payload["overrides"])
    widen = payload.get("widen", {})
    variants = payload.get("variants", {})  # absent in runs from before sweeps
    configs, warnings = {}, []
    for method in payload["methods"]:
      configs[method], notes = _saved_config(payload, method, spec, overrides, widen)
      warnings += [f"{path}: {method} {note}" for note in notes]
    check_plan(payload["task"], spec, configs)
    physics = folder.saved_physics(payload)
    contacts = folder.saved_contacts(payload)
    folder.check_process_count(payload)
    moved = provenance.host_differs(payload)
    if moved:
      warnings.append(f"{path}: started on another machine type ({moved}): the rows after "
                      "this resume are rounded as on this one, so the run as a whole "
                      "reproduces on neither")
  except (ValueError, TypeError, KeyError) as e:
    raise ValueError(f"{path}: {e}") from None
  return Plan(task=payload["task"], preset=payload["preset"], seed=payload["seed"], out=out,
              spec=spec, configs=configs, overrides=overrides, widen=widen, warnings=warnings,
              variants=variants, grouped=payload.get("grouped", False) is True, physics=physics,
              contacts=contacts)


def _saved_config(payload, name: str, spec, overrides: dict, widen: dict):
  """(the saved config of the variant ``name``, notes on how it differs from today's
  preset)."""
  saved = payload["configs"].get(name)
  if saved is None:
    raise ValueError(f"configs has no entry for the method {name!r}")
  variant = payload.get("variants", {}).get(name, {"method": name, "overrides": {}})
  overrides = {**overrides, **flatten(variant["overrides"])}
  try:
    today, _ = methods.build_config(payload["preset"], variant["method"], payload["task"],
                                    overrides, dataclasses.asdict(spec), widen)
  except ValueError as e:
    today, notes = None, [f"cannot be rebuilt from today's presets ({e}); config.json is used"]
  try:
    config = config_from_dict(saved, _earlier_behaviour(saved, today))
  except ValueError as e:
    raise ValueError(f"configs.{name}: {e}") from None
  if today is None:
    return config, notes
  notes = []
  missing = missing_fields(saved, today)
  if missing:
    notes.append(f"has no {', '.join(missing)} (newer fields): their defaults, the behaviour "
                 f"before they were added, are used")
  changed = [p for p in differences(config, today) if p not in missing]
  if changed:
    shown = "; ".join(f"{p} {get(config, p)!r} (today {get(today, p)!r})" for p in changed)
    notes.append(f"differs from today's {payload['preset']} preset with its overrides: {shown}; "
                 f"the run keeps its config.json")
  return config, notes


def _earlier_behaviour(saved, today: AgentConfig | None) -> AgentConfig:
  """The base a saved config is read over: today's preset, with every field the saved one
  lacks (added to the code since) at its ``AgentConfig()`` default, which is the behaviour
  before the field existed (a new option keeps the earlier behaviour as its default; the
  presets may take the new one), so that an old run resumes and reproduces as it ran."""
  if today is None:
    return AgentConfig()
  default = AgentConfig()
  return override(today, {p: get(default, p) for p in missing_fields(saved, today)})


