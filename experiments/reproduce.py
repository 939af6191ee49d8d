"""Does a run folder reproduce here? ``python -m experiments.reproduce results/pointfall/hiro``.

Re-runs the folder's plan (its ``config.json``: task, methods, every config, seeds, ``--seed``,
device count) from step 0 in a temporary folder, up to ``--steps`` env steps (default: the
whole run), and compares every row it writes with the folder's ``metrics.csv``, field by
field as text. The rows are the same only on the machine type the run was made on (the host
``config.json`` records: XLA:CPU compiles for the CPU it runs on, ``benchmarks/cpu_profile.md``),
so the first line says whether this host is that type (and a second, whether the run was
resumed at another commit or on another machine type: its ``sessions.jsonl``).

    python -m experiments.reproduce results/pointfall/hiro --steps 20000      # 100 rows
    python -m experiments.reproduce results/pointmaze/ours --steps 10000 --method ours

A CPU run is re-run on the device count it trained on (``config.json``'s ``device_count``).

The unit is the folder's command: a seed's key is split from ``--seed`` for the run's seed
count and a program of 10 lanes rounds differently from one of 1, so the plan is re-run whole
(a group of variants that ran as one program is re-run as that program; ``--method`` only
picks which rows are compared). Exit codes: 0 every compared row equal, 1 some differ, 2 bad
input (no run folder, an unknown method, a run that needs another device count than JAX has).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import io as text_io
import sys
import tempfile

from nonmono_jax.host import folder, plan as plan_lib, provenance, rows as rows_lib, run

EXIT_DIFFER, EXIT_BAD_INPUT = 1, 2


@dataclasses.dataclass
class Comparison:
  """The rows of one method compared so far."""

  method: str
  columns: tuple = rows_lib.COLUMNS  # the folder's metrics.csv's (an earlier version's: fewer)
  equal: int = 0
  missing: int = 0  # rows the folder does not have (it stopped earlier)
  differ: list = dataclasses.field(default_factory=list)  # (env_step, seed, [(col, a, b)])
  last_step: int = 0

  def add(self, committed: dict, rows) -> None:
    for row in rows:
      key = (row["method"], int(row["env_step"]), int(row["seed"]))
      self.last_step = max(self.last_step, key[1])
      line = committed.get(key)
      if line is None:
        self.missing += 1
      elif line == format_row(row, self.columns):
        self.equal += 1
      else:
        self.differ.append((key[1], key[2], changed_fields(line, format_row(row, self.columns),
                                                           self.columns)))

  def report(self) -> str:
    compared = self.equal + len(self.differ)
    head = f"{self.method}: env steps up to {self.last_step}, {compared} rows compared"
    if self.missing:
      head += f" ({self.missing} more not in the folder's metrics.csv)"
    if not self.differ:
      return f"{head}: all equal" if compared else f"{head}: nothing to compare"
    step, seed, fields = self.differ[0]
    shown = "; ".join(f"{c} {a} there, {b} here" for c, a, b in fields[:3])
    return (f"{head}: {len(self.differ)} differ, the first at env step {step} (seed {seed}: "
            f"{shown}{'; ...' if len(fields) > 3 else ''})")


def format_row(row: dict, columns=rows_lib.COLUMNS) -> str:
  """A row as ``metrics.csv`` holds it (``rows.MetricsFile.append``), without the newline; a
  file of an earlier version has fewer ``columns``."""
  buffer = text_io.StringIO()
  csv.DictWriter(buffer, columns, lineterminator="\n", extrasaction="ignore").writerow(row)
  return buffer.getvalue()[:-1]


def changed_fields(line_a: str, line_b: str, columns=rows_lib.COLUMNS) -> list:
  """[(column, value in a, value in b)] where two ``metrics.csv`` lines differ."""
  a, b = next(csv.reader([line_a])), next(csv.reader([line_b]))
  return [(c, x, y) for c, x, y in zip(columns, a, b) if x != y]


def committed_rows(folder: str) -> dict:
  """(method, env_step, seed) -> the line of the folder's ``metrics.csv``."""
  path = f"{folder}/metrics.csv"
  out = {}
  for line in rows_lib.good_lines(path):
    values = next(csv.reader([line]))
    out[values[1], int(values[3]), int(values[2])] = line
  return out


def moved_line(out: str) -> str | None:
  """What the run's sessions say of a resume at another commit or on another machine type
  (``sessions.jsonl``), or None: a re-run here from step 0 repeats its rows up to there at
  most."""
  moves = provenance.moves(folder.read_sessions(out))
  if moves:
    return (f"{'; '.join(moves)}: its rows from then on are that session's, and a re-run from "
            f"step 0 can repeat them only up to there")
  return None


def host_line(payload: dict) -> str:
  saved = payload.get("host")
  if not isinstance(saved, dict):
    return ("the folder does not record the machine it ran on (a run from before hosts were "
            "recorded): rows can differ here for that reason alone")
  made_on = (f"{saved.get('cpu')} (family {saved.get('cpu_family')}, model "
             f"{saved.get('cpu_model')})")
  moved = provenance.host_differs(payload)
  if moved:
    return (f"made on {made_on}; this host differs ({moved}): expect the rows to part after "
            f"the first updates")
  return f"made on {made_on}; this host is the same machine type"


def reproduce(folder: str, steps: int | None, wanted: list[str] | None, log=print) -> list:
  """Re-runs the plan in ``folder`` to ``steps`` env steps (None: all) and compares; the
  Comparison of each wanted method (default: all of the plan's)."""
  plan = plan_lib.load_run(folder)
  wanted = wanted or list(plan.configs)
  unknown = sorted(set(wanted) - set(plan.configs))
  if unknown:
    raise ValueError(f"{folder} has no method {', '.join(unknown)} (it has "
                     f"{', '.join(plan.configs)})")
  committed = committed_rows(folder)
  columns = rows_lib.file_columns(f"{folder}/metrics.csv")
  results = {m: Comparison(m, columns) for m in wanted}
  with tempfile.TemporaryDirectory() as tmp:
    plan = dataclasses.replace(plan, out=tmp, warnings=[])
    for group in plan.groups():
      if set(group) & set(wanted):
        _rerun_group(plan, group, steps, committed, results, log)
  return [results[m] for m in wanted]


def _rerun_group(plan, group, steps, committed, results, log) -> None:
  """One program of the plan from step 0 until ``steps`` env steps, its rows compared."""
  log(f"{', '.join(group)}: re-running from step 0"
      + (f" to env step {steps}" if steps else f" to the end ({plan.spec.steps} steps)"))
  with contextlib.closing(run.run_group(plan, group, outputs=(), log=log)) as chunks:
    for result in chunks:
      if result.method in results:
        results[result.method].add(committed, result.rows)
      if steps and result.env_step >= steps and result.method == group[-1]:
        break


def make_parser() -> argparse.ArgumentParser:
  p = argparse.ArgumentParser(
      prog="python -m experiments.reproduce",
      description="Re-run a run folder's plan and compare its rows with its metrics.csv.")
  p.add_argument("folder", help="a run folder (config.json and metrics.csv)")
  p.add_argument("--steps", type=int, default=None,
                 help="env steps to re-run and compare (default: the whole run)")
  p.add_argument("--method", nargs="+", default=None,
                 help="the methods whose rows are compared (default: all of the folder's)")
  return p


def main(argv=None) -> int:
  p = make_parser()
  args = p.parse_args(argv)
  try:
    if args.steps is not None and args.steps <= 0:
      raise ValueError(f"--steps must be positive, got {args.steps}")
    payload = folder.read_config(args.folder)
    if payload.get("platform") == "cpu" and isinstance(payload.get("device_count"), int):
      run.use_cpu_devices(payload["device_count"])  # the device count the run trained on
    print(f"{args.folder}: {host_line(payload)}", flush=True)
    moved = moved_line(args.folder)
    if moved:
      print(f"{args.folder}: {moved}", flush=True)
    comparisons = reproduce(args.folder, args.steps, args.method)
  except (ValueError, rows_lib.MetricsError) as e:
    print(f"{p.prog}: error: {e}", file=sys.stderr)
    return EXIT_BAD_INPUT
  for c in comparisons:
    print(c.report(), flush=True)
  return EXIT_DIFFER if any(c.differ for c in comparisons) else 0


if __name__ == "__main__":
  sys.exit(main())
