"""What every benchmark records: the machine, the command, the date, and the result file."""

from __future__ import annotations

import datetime
import json
import os
import platform
import sys

import jax

RESULTS = os.path.join(os.path.dirname(__file__), "results")


def machine() -> dict:
  dev = jax.devices()[0]
  return {"platform": dev.platform, "device": str(dev.device_kind), "cpu_count": os.cpu_count(),
          "processor": platform.processor() or platform.machine(),
          "python": platform.python_version(), "jax": jax.__version__}


def write_result(name: str, out_dir: str, argv: list[str] | None, **payload) -> str:
  """Write ``<out_dir>/<name>_<platform>_<date>.json`` with the command that made it."""
  date = datetime.date.today().isoformat()
  info = machine()
  args = sys.argv[1:] if argv is None else argv
  result = {"benchmark": name, "date": date, "machine": info,
            "command": " ".join(["python -m", f"benchmarks.{name}", *args]), **payload}
  os.makedirs(out_dir, exist_ok=True)
  path = os.path.join(out_dir, f"{name}_{info['platform']}_{date}.json")
  with open(path, "w") as f:
    json.dump(result, f, indent=2)
  print("wrote", path)
  return path
