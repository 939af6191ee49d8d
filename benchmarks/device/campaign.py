"""A plan of GPU stages (benchmarks, experiments), carried across 10-minute device commands.

The lent GPU machine runs one command for at most 10 minutes, stays warm (keeping its disk)
only while commands follow each other, gives back at most 8 files of 16 MiB per command, and
lends 30 device minutes per session. A paper-size checkpoint is about 460 MB per seed (the
replay buffers; 15 MB without them), so training state cannot travel between sessions: it
stays on the machine's disk, and what travels is the small part, metrics and benchmark rows.

So a plan is a list of stages, each a command of this repo, run in order:

- ``experiment``: ``python -m experiments.<task> ARGV``. It gets the command's remaining time
  as ``--time-limit``, stops checkpointed (exit 3) and continues with ``--resume`` in the next
  command, exactly (checkpoints stay on the machine in ``--work``). An experiment must finish
  within one session; one that a session leaves unfinished starts over in the next.
- ``benchmark``: ``python -m MODULE ARGV --out DIR``. It starts only if ``estimate_s`` fits
  in the time left, and writes its rows as it goes (a killed one keeps what it measured).

On the device, every command (the same command each time; stages done are skipped):

    source benchmarks/device/setup.sh && \\
      python -m benchmarks.device.campaign benchmarks/device/plans/gpu.json --out $OUT

Here, after each command (``files_at`` of its reply):

    python -m benchmarks.device.campaign benchmarks/device/plans/gpu.json --collect FILES_AT

which puts each experiment's ``config.json``, ``metrics.csv`` and log into its ``results``
folder (``results/<task>/<stage>/``), draws the figures, moves benchmark results into
``benchmarks/results/`` and records the plan's progress in ``benchmarks/device/state/``
(commit them: the next session's command skips what is done). ``--status`` prints it.
"""

from __future__ import annotations

import argparse
import dataclasses
import glob
import io as _io
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
STATE_DIR = os.path.join("benchmarks", "device", "state")  # in the repo: committed
# This process only starts the stages and must not hold the GPU: it imports nothing that
# imports jax (a jax process that touches the GPU takes 75 % of its memory by default), so the
# two pieces below repeat experiments.cli.EXIT_TIME_LIMIT and nonmono_jax.io.write_json.
EXIT_TIME_LIMIT = 3
# What one command may give back ($OUT): files, size of each, size in all (device README).
MAX_FILES, MAX_FILE_BYTES, MAX_TOTAL_BYTES = 8, 16 * 2**20, 64 * 2**20
EXPORT = "results.tar.gz"
MIN_STAGE_S = 30.0  # no stage starts with less time left than this
KINDS = ("experiment", "benchmark")


@dataclasses.dataclass(frozen=True)
class Stage:
  id: str
  kind: str
  argv: tuple[str, ...]
  task: str | None = None  # experiment: the experiments.<task> module
  results: str | None = None  # experiment: folder (in the repo) that --collect fills
  estimate_s: float = 0.0  # benchmark: device seconds it needs (it starts only if they fit)

  def __post_init__(self):
    if not self.id or not all(ch.isalnum() or ch in "-_." for ch in self.id):
      raise ValueError(f"stage id must be letters, digits, '-', '_' or '.', got {self.id!r}")
    if self.kind not in KINDS:
      raise ValueError(f"stage {self.id}: kind must be one of {', '.join(KINDS)}, "
                       f"got {self.kind!r}")
    if self.kind == "experiment" and not (self.task and self.results):
      raise ValueError(f"stage {self.id}: an experiment needs 'task' and 'results'")
    if self.kind == "benchmark" and not self.argv:
      raise ValueError(f"stage {self.id}: a benchmark needs 'argv' (its module first)")
    if self.estimate_s < 0:
      raise ValueError(f"stage {self.id}: estimate_s must be >= 0, got {self.estimate_s}")


@dataclasses.dataclass(frozen=True)
class Plan:
  name: str
  stages: tuple[Stage, ...]

  @classmethod
  def load(cls, path: str) -> "Plan":
    with open(path) as f:
      payload = json.load(f)
    stages = tuple(Stage(**{**s, "argv": tuple(s.get("argv", ()))}) for s in payload["stages"])
    ids = [s.id for s in stages]
    if len(set(ids)) != len(ids):
      raise ValueError(f"stage ids must be unique, got {ids}")
    return cls(payload["name"], stages)


# --- the plan's progress ------------------------------------------------------------------------

def state_path(plan: Plan, repo: str = ROOT) -> str:
  return os.path.join(repo, STATE_DIR, f"{plan.name}.json")


def _write_json(path: str, payload) -> None:
  """Atomically (see the note on imports at the top)."""
  os.makedirs(os.path.dirname(path), exist_ok=True)
  tmp = path + ".tmp"
  with open(tmp, "w") as f:
    json.dump(payload, f, indent=1, sort_keys=True)
  os.replace(tmp, path)


def load_state(plan: Plan, work: str, repo: str = ROOT) -> dict:
  """stage id -> {status, device_s, commands, exit}; status: todo, running, done, failed,
  partial. The machine's copy (``work``) wins; else the committed one, whose unfinished
  experiments start over (their checkpoints were on a machine that is gone)."""
  for path, fresh in ((os.path.join(work, "state.json"), False),
                      (state_path(plan, repo), True)):
    if os.path.exists(path):
      with open(path) as f:
        state = json.load(f)
      if fresh:
        for s in state.values():
          if s["status"] == "running":
            s.update(status="todo", restarts=s.get("restarts", 0) + 1)
      break
  else:
    state = {}
  for stage in plan.stages:
    state.setdefault(stage.id, {"status": "todo", "device_s": 0.0, "commands": 0, "exit": None})
  return state


# --- running stages on the device ---------------------------------------------------------------

def _run(argv: list[str], log_path: str, timeout: float) -> int:
  """Run ``python -m ARGV`` in the repo with its output appended to ``log_path``; the exit
  code, or -9 if it was killed at ``timeout`` seconds."""
  env = {**os.environ, "PYTHONUNBUFFERED": "1",
         "PYTHONPATH": os.pathsep.join(filter(None, [ROOT, os.environ.get("PYTHONPATH")]))}
  with open(log_path, "a") as log:
    log.write(f"\n$ {' '.join(argv)}\n")
    log.flush()
    try:
      return subprocess.run([sys.executable, "-m", *argv], cwd=ROOT, env=env, stdout=log,
                            stderr=subprocess.STDOUT, timeout=max(timeout, 1.0)).returncode
    except subprocess.TimeoutExpired:
      return -9


def _tail(path: str, lines: int = 8) -> str:
  with open(path, errors="replace") as f:
    return "".join(f.readlines()[-lines:])


def run_stage(stage: Stage, work: str, time_left: float) -> int:
  folder = os.path.join(work, stage.id)
  os.makedirs(folder, exist_ok=True)
  log = os.path.join(folder, "log.txt")
  if stage.kind == "experiment":
    run_dir = os.path.join(folder, "run")
    module = f"experiments.{stage.task.lower()}"
    if os.path.exists(os.path.join(run_dir, "config.json")):
      argv = [module, "--resume", run_dir]
    else:
      argv = [module, *stage.argv, "--out", run_dir]
    # The run stops itself before a chunk that would end past its limit; the hard timeout
    # (30 s later) only catches a chunk much slower than the one before it.
    argv += ["--no-progress", "--time-limit", f"{max(time_left, 0.0):.0f}"]
    code = _run(argv, log, time_left + 30)
  else:
    code = _run([*stage.argv, "--out", os.path.join(folder, "out")], log, time_left)
  print(f"[{stage.id}] exit {code}\n{_tail(log)}", flush=True)
  return code


def run_plan(plan: Plan, work: str, budget: float, reserve: float = 20.0) -> dict:
  """Run the plan's stages in order until done or ``budget`` seconds (less ``reserve`` for
  the export) are spent; returns the updated state (also written to ``work/state.json``)."""
  start = time.monotonic()
  os.makedirs(work, exist_ok=True)
  state = load_state(plan, work)
  for stage in plan.stages:
    s = state[stage.id]
    if s["status"] in ("done", "failed", "partial"):
      continue
    left = budget - reserve - (time.monotonic() - start)
    need = max(stage.estimate_s, MIN_STAGE_S)
    if left < need:
      print(f"[{stage.id}] needs {need:.0f} s, {left:.0f} s left: next command", flush=True)
      break
    t0 = time.monotonic()
    code = run_stage(stage, work, left)
    s["device_s"] += time.monotonic() - t0
    s["commands"] += 1
    s["exit"] = code
    if code == 0:
      s["status"] = "done"
    elif stage.kind == "experiment" and code in (EXIT_TIME_LIMIT, -9):
      s["status"] = "running"  # -9: killed in a chunk; it resumes from its last checkpoint
    elif stage.kind == "benchmark" and code == -9:
      s["status"] = "partial"  # killed at its time: the rows it wrote are kept
    else:
      s["status"] = "failed"
    _write_json(os.path.join(work, "state.json"), state)
    if s["status"] == "running":
      break  # the time is up
  _write_json(os.path.join(work, "state.json"), state)
  return state


# --- what comes back, and what is done with it here ---------------------------------------------

def _small_files(plan: Plan, work: str):
  """(path on disk, name in the archive) of everything but checkpoints and caches."""
  yield os.path.join(work, "state.json"), "state.json"
  for stage in plan.stages:
    folder = os.path.join(work, stage.id)
    for path in sorted(glob.glob(os.path.join(folder, "**", "*"), recursive=True)):
      rel = os.path.relpath(path, work)
      if os.path.isfile(path) and "checkpoints" not in rel.split(os.sep):
        yield path, rel


def export(plan: Plan, work: str, out: str, state: dict) -> list[str]:
  """Pack the results into ``out`` within the device's limits on what comes back: one
  ``results.tar.gz``, split into ``results.tar.gz.partNN`` if it is over one file's size."""
  buf = _io.BytesIO()
  with tarfile.open(fileobj=buf, mode="w:gz") as tar:
    info = tarfile.TarInfo("plan.json")
    payload = json.dumps({"name": plan.name, "state": state}).encode()
    info.size = len(payload)
    tar.addfile(info, _io.BytesIO(payload))
    for path, name in _small_files(plan, work):
      tar.add(path, arcname=name)
  data = buf.getvalue()
  return write_parts(data, out)


def write_parts(data: bytes, out: str, name: str = EXPORT) -> list[str]:
  if len(data) > MAX_TOTAL_BYTES:
    raise ValueError(f"the results are {len(data) / 2**20:.1f} MiB, over the "
                     f"{MAX_TOTAL_BYTES // 2**20} MiB a device command can give back")
  os.makedirs(out, exist_ok=True)
  if len(data) <= MAX_FILE_BYTES:
    parts = [(name, data)]
  else:
    parts = [(f"{name}.part{i:02d}", data[o:o + MAX_FILE_BYTES])
             for i, o in enumerate(range(0, len(data), MAX_FILE_BYTES))]
  if len(parts) > MAX_FILES:
    raise ValueError(f"{len(parts)} files, over the {MAX_FILES} a command can give back")
  paths = []
  for n, chunk in parts:
    path = os.path.join(out, n)
    with open(path, "wb") as f:
      f.write(chunk)
    paths.append(path)
  return paths


def read_parts(folder: str, name: str = EXPORT) -> bytes:
  whole = os.path.join(folder, name)
  if os.path.exists(whole):
    with open(whole, "rb") as f:
      return f.read()
  parts = sorted(glob.glob(os.path.join(folder, f"{name}.part*")))
  if not parts:
    raise FileNotFoundError(f"no {name} (or {name}.partNN) in {folder}")
  return b"".join(open(p, "rb").read() for p in parts)


def collect(plan: Plan, folder: str, repo: str = ROOT, figures: bool = True) -> dict:
  """Unpack a command's results into the repo (see the module docstring)."""
  data = read_parts(folder)
  with tempfile.TemporaryDirectory() as tmp:
    with tarfile.open(fileobj=_io.BytesIO(data), mode="r:gz") as tar:
      tar.extractall(tmp, filter="data")
    with open(os.path.join(tmp, "plan.json")) as f:
      payload = json.load(f)
    if payload["name"] != plan.name:
      raise ValueError(f"these results are of plan {payload['name']!r}, not {plan.name!r}")
    state = payload["state"]
    drawn = set()
    for stage in plan.stages:
      src = os.path.join(tmp, stage.id)
      if not os.path.isdir(src):
        continue
      if stage.kind == "experiment":
        dst = os.path.join(repo, stage.results, stage.id)
        os.makedirs(dst, exist_ok=True)
        for name in ("config.json", "metrics.csv"):
          if os.path.exists(os.path.join(src, "run", name)):
            shutil.copy(os.path.join(src, "run", name), os.path.join(dst, name))
        shutil.copy(os.path.join(src, "log.txt"), os.path.join(dst, "log.txt"))
        drawn.add(os.path.join(repo, stage.results))
      else:
        dst = os.path.join(repo, "benchmarks", "results")
        os.makedirs(dst, exist_ok=True)
        for path in glob.glob(os.path.join(src, "out", "*.json")):
          shutil.copy(path, dst)
        shutil.copy(os.path.join(src, "log.txt"), os.path.join(dst, f"{stage.id}.log"))
  _write_json(state_path(plan, repo), state)
  if figures:
    from experiments import plot

    for results in sorted(drawn):
      runs = sorted(d for d in glob.glob(os.path.join(results, "*"))
                    if os.path.exists(os.path.join(d, "metrics.csv")))
      plot.main([*runs, "--out", os.path.join(results, "figures")])
  return state


def status_lines(plan: Plan, state: dict) -> list[str]:
  lines = [f"plan {plan.name}:"]
  for stage in plan.stages:
    s = state.get(stage.id, {"status": "todo", "device_s": 0.0, "commands": 0})
    lines.append(f"  {stage.id:28s} {s['status']:8s} {s['device_s'] / 60:6.1f} device min, "
                 f"{s['commands']} commands")
  return lines


def main(argv=None) -> int:
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("plan", help="a plan file, e.g. benchmarks/device/plans/gpu.json")
  p.add_argument("--budget", type=float, default=510.0,
                 help="seconds the stages may take in this command (the device allows 600 per "
                      "command, of which setup.sh and the export take some)")
  p.add_argument("--work", default=None,
                 help="folder on the machine for runs and checkpoints (default: "
                      "runs/campaign/<plan>; kept between commands while the machine is warm)")
  p.add_argument("--out", default=os.environ.get("OUT"),
                 help="where the results to give back go (default: $OUT)")
  p.add_argument("--collect", metavar="FOLDER",
                 help="here: unpack the results a command gave back into the repo")
  p.add_argument("--status", action="store_true", help="print the plan's progress")
  args = p.parse_args(argv)
  try:
    plan = Plan.load(args.plan)
  except (ValueError, TypeError, KeyError) as e:
    p.error(f"{args.plan}: {e}")
  work = args.work or os.path.join(ROOT, "runs", "campaign", plan.name)
  if args.collect:
    state = collect(plan, args.collect)
    print("\n".join(status_lines(plan, state)))
    return 0
  if args.status:
    print("\n".join(status_lines(plan, load_state(plan, work))))
    return 0
  if not args.out:
    p.error("--out is needed (or $OUT set): where the results to give back go")
  state = run_plan(plan, work, args.budget)
  paths = export(plan, work, args.out, state)
  print("\n".join(status_lines(plan, state)))
  print("gave back", ", ".join(f"{os.path.basename(x)} ({os.path.getsize(x) / 2**20:.2f} MiB)"
                               for x in paths))
  return 0


if __name__ == "__main__":
  sys.exit(main())
