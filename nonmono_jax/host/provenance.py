"""Where a run was made: the machine type its rows reproduce on, the code's commit, the
libraries' versions (``config.json`` records ``made()``).

Rows reproduce bit for bit only on the same kind of CPU (XLA:CPU picks its code for the CPU it
finds) and from the same commit (later code may round a run differently).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from importlib import metadata

import jax

PACKAGES = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "brax", "flax", "optax", "orbax-checkpoint",
            "numpy", "nonmono-jax")


def made() -> dict:
  """What ``config.json`` records of where and how a run was made."""
  return {"versions": versions(), "code": code_version(), "python": platform.python_version(),
          "device": str(jax.devices()[0].device_kind), "platform": jax.default_backend(),
          "device_count": jax.device_count(), "processes": jax.process_count(),
          "host": host(), "command": " ".join(sys.argv)}


# The instruction sets XLA:CPU's code (and its matmul kernels) may use: two CPUs that differ in
# them round a run differently, so its rows reproduce only on the same kind of CPU.
ISA_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_vnni", "avx512_bf16", "amx_tile")


def host() -> dict:
  """The machine type a run's rows reproduce on: CPU model (``/proc/cpuinfo``), its
  instruction sets from ``ISA_FLAGS``, core count and ``XLA_FLAGS``."""
  info = {}
  try:
    with open("/proc/cpuinfo") as f:
      for line in f:
        key, _, value = line.partition(":")
        info.setdefault(key.strip(), value.strip())
  except OSError:
    pass
  flags = set(info.get("flags", "").split())
  return {"cpu": info.get("model name") or platform.processor() or platform.machine(),
          "cpu_family": info.get("cpu family"), "cpu_model": info.get("model"),
          "isa": [f for f in ISA_FLAGS if f in flags], "cores": os.cpu_count(),
          "xla_flags": os.environ.get("XLA_FLAGS", "")}


# What makes another machine type (another CPU or instruction set: XLA:CPU's code differs), and
# what else rounds a run differently; the core count does neither.
MACHINE_KEYS = ("cpu", "cpu_family", "cpu_model", "isa")
ROUNDING_KEYS = (*MACHINE_KEYS, "xla_flags")


def host_changes(before: dict, after: dict) -> list[str]:
  """The keys of ``host()`` (of ``ROUNDING_KEYS``) in which two recorded hosts differ."""
  return [k for k in ROUNDING_KEYS if before.get(k) != after.get(k)]


def host_differs(payload) -> str | None:
  """What differs between the host that started the run in ``payload`` (``config.json``) and
  this one, or None (also for runs from before hosts were recorded)."""
  saved, now = payload.get("host"), host()
  if not isinstance(saved, dict):
    return None
  changed = [f"{k} {saved.get(k)!r} (here {now[k]!r})" for k in host_changes(saved, now)]
  return "; ".join(changed) or None


def code_version() -> dict:
  """The commit of the code that made the run, where it runs from a git checkout: ``{"commit":
  sha, "dirty": uncommitted changes to tracked files}``; ``{}`` elsewhere (an installed wheel).
  Later code may round a run differently: the commit is where it reproduces bit for bit."""
  here = os.path.dirname(os.path.abspath(__file__))
  git = lambda *args: subprocess.run(["git", "-C", here, *args], capture_output=True,
                                     text=True, timeout=10)
  try:
    head = git("rev-parse", "HEAD")
    if head.returncode:
      return {}
    dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip() != ""
  except (OSError, subprocess.SubprocessError):
    return {}
  return {"commit": head.stdout.strip(), "dirty": dirty}


def session(resumed: bool) -> dict:
  """A line of the run folder's ``sessions.jsonl``: a process that opened the run to train
  it, with its code and machine. ``config.json`` holds the first's; a run resumed at another
  commit or on another machine type reproduces bit for bit up to there only."""
  return {"started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "resumed": resumed,
          "code": code_version(), "host": host(), "command": " ".join(sys.argv)}


def moves(sessions: list) -> list[str]:
  """Where each session of a run (``sessions.jsonl``'s lines) ran at another commit or on
  another machine type than the session before it: one phrase each, in order."""
  out = []
  for before, now in zip(sessions, sessions[1:]):
    changed = []
    if (before.get("code") or {}).get("commit") != (now.get("code") or {}).get("commit"):
      changed.append(f"at commit {str((now.get('code') or {}).get('commit'))[:7]}")
    b = now.get("host") or {}
    keys = host_changes(before.get("host") or {}, b)
    if set(keys) & set(MACHINE_KEYS):
      changed.append(f"on {b.get('cpu')} (family {b.get('cpu_family')}, model "
                     f"{b.get('cpu_model')})")
    if "xla_flags" in keys:
      changed.append(f"with XLA_FLAGS {b.get('xla_flags')!r}")
    if changed:
      out.append(f"resumed {' and '.join(changed)} on {now.get('started')}")
  return out


def versions() -> dict:
  """The version of each of ``PACKAGES`` installed (None: not installed)."""
  out = {}
  for name in PACKAGES:
    try:
      out[name] = metadata.version(name)
    except metadata.PackageNotFoundError:
      out[name] = None
  return out
