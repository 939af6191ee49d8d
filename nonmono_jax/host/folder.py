"""The run folder's files: written atomically, and ``config.json``, the run's source of truth.

    out/config.json                 everything needed to rerun (configs, versions, device)
    out/metrics.csv                 the rows (``rows.py``)
    out/checkpoints/<method>/<step> orbax checkpoints of the train state (``checkpoints.py``)
    out/timing.json                 the longest first (compiling) chunk, for --time-limit
    out/sessions.jsonl              each process that trained it: when, its commit and machine

``to_json(plan)`` is ``config.json``: the plan (task, methods, every config in full, the run's
size, overrides, the ant's physics) and where it was made (``provenance.py``).
``read_config(out)`` reads it back, ``check_payload`` checks its keys and types before anything
is taken from it; ``plan.load_run`` turns it into a ``Plan``. What an older ``config.json``
lacks (a field added since, a run from before the physics choice) is filled in one place each:
``saved_physics``, ``saved_contacts``, and ``plan._earlier_behaviour`` for the configs.
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any

import jax

import envs
from envs import contacts as contacts_lib
from envs import physics as physics_lib
from nonmono_jax.host import methods, provenance

SESSIONS = "sessions.jsonl"


def to_jsonable(obj: Any) -> Any:
  """Dataclasses (configs) and tuples to plain JSON values."""
  if dataclasses.is_dataclass(obj):
    return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
  if isinstance(obj, (list, tuple)):
    return [to_jsonable(x) for x in obj]
  if isinstance(obj, dict):
    return {k: to_jsonable(v) for k, v in obj.items()}
  return obj


def write_text(path: str, text: str) -> None:
  """Atomically (a synced temporary file renamed over ``path``), line endings as given."""
  tmp = path + ".tmp"
  with open(tmp, "w", newline="") as f:
    f.write(text)
    f.flush()
    os.fsync(f.fileno())
  os.replace(tmp, path)


def write_json(path: str, payload: dict) -> None:
  """Atomically: a temporary file renamed over ``path``."""
  write_text(path, json.dumps(payload, indent=1, sort_keys=True))


def add_session(out: str, resumed: bool) -> None:
  """Appends this process's line to ``OUT/sessions.jsonl`` (``provenance.session``)."""
  with open(os.path.join(out, SESSIONS), "a") as f:
    f.write(json.dumps(provenance.session(resumed), sort_keys=True) + "\n")


def read_sessions(out: str) -> list:
  """``OUT/sessions.jsonl``'s lines ([] for a run from before sessions were recorded); a
  line cut short by a stop is left out."""
  try:
    with open(os.path.join(out, SESSIONS)) as f:
      lines = f.read().splitlines()
  except FileNotFoundError:
    return []
  sessions = []
  for line in lines:
    try:
      sessions.append(json.loads(line))
    except json.JSONDecodeError:
      continue
  return sessions


def read_json(path: str) -> dict:
  with open(path) as f:
    return json.load(f)


def read_config(out: str):
  """``OUT/config.json`` as JSON; raises ValueError naming the file."""
  path = os.path.join(out, "config.json")
  if not os.path.isfile(path):
    raise ValueError(f"{out}: no config.json there (not a run folder)")
  try:
    return read_json(path)
  except (OSError, UnicodeDecodeError) as e:
    raise ValueError(f"{path}: cannot be read ({e})") from None
  except ValueError as e:
    raise ValueError(f"{path}: not valid JSON ({e})") from None


def to_json(plan) -> dict:
  """``config.json`` of a ``plan.Plan``: the plan (every config in full) and where it was made
  (``provenance.made``: library versions, commit, device, host, command)."""
  return {"task": plan.task, "preset": plan.preset, "seed": plan.seed,
          "methods": list(plan.configs), "run": to_jsonable(plan.spec),
          "overrides": to_jsonable(plan.overrides), "widen": plan.widen,
          "configs": {m: to_jsonable(c) for m, c in plan.configs.items()},
          "variants": to_jsonable(plan.variants), "grouped": plan.grouped,
          "physics": plan.physics, "contacts": plan.contacts, **provenance.made()}


# --- reading it back: what each key must be, and what an older file lacks --------------------

def check_process_count(payload) -> None:
  """A run resumes with the process count it was made with (each process restores the
  checkpoint shards of its own lanes)."""
  made = payload.get("processes", 1)
  if made != jax.process_count():
    how = (f"--distributed with {made} processes" if made > 1 else "one process, without "
           "--distributed")
    raise ValueError(f"the run was made by {made} process(es), this is {jax.process_count()}: "
                     f"resume it with {how}")


def _saved_choice(payload, key: str, before: str, allowed) -> str | None:
  """``payload[key]``, one of ``allowed``, for an ant task (null otherwise); ``before`` for an
  ant run written before the choice existed (what it ran on)."""
  task, value = payload["task"], payload.get(key)
  if not envs.has_physics(task):
    if value is not None:
      raise ValueError(f"{key} must be null for {task}, got {value!r}")
    return None
  if value is None:
    return before
  if value not in allowed:
    choices = " or ".join(allowed) if len(allowed) == 2 else f"one of {', '.join(allowed)}"
    raise ValueError(f"{key} must be {choices}, got {value!r}")
  return value


def saved_physics(payload) -> str | None:
  """The physics a saved run trained with: its ``physics`` entry; for an ant run from before
  the choice, ``mjx`` (what it ran on)."""
  return _saved_choice(payload, "physics", "mjx", physics_lib.ENGINES)


def saved_contacts(payload) -> str | None:
  """The contact settings a saved run trained with: its ``contacts`` entry; for an ant run from
  before the choice, ``mujoco3`` (what it ran on)."""
  return _saved_choice(payload, "contacts", "mujoco3", contacts_lib.CONTACTS)


def check_payload(payload) -> None:
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
  if set(payload["run"]) != set(methods.RUN_FIELDS):
    raise ValueError(f"run must have exactly the keys {', '.join(sorted(methods.RUN_FIELDS))}")
  for key, value in payload["run"].items():
    if not isinstance(value, int) or isinstance(value, bool):
      raise ValueError(f"run.{key} must be an integer, got {value!r}")
  if not isinstance(payload.get("widen", {}), dict):
    raise ValueError("widen must be an object")
  for name, variant in payload.get("variants", {}).items():
    if not (isinstance(variant, dict) and isinstance(variant.get("method"), str)
            and isinstance(variant.get("overrides"), dict)):
      raise ValueError(f"variants.{name} must be an object with a method and its overrides")
