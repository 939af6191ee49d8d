"""Where a run's chunk results go: each sink has ``begin`` (a method starts or resumes),
``write`` (one ``run.ChunkResult``) and ``close``; ``closing`` closes them all on any exit.

    MetricsCsv(out)          OUT/metrics.csv: the paper's columns (``rows.COLUMNS``), one row per
                             method, seed and chunk
    JsonLines(out)           OUT/metrics.jsonl: those columns and every metric the program
                             computes (``train.reduce_chunk``'s keys), one line per seed and chunk
    TensorBoard(out)         OUT/tensorboard/<method>: means over seeds of both, S_E per seed
    WandB(plan, project)     the same scalars to Weights & Biases, one W&B run per method
    Progress(plan, enabled)  a tqdm bar, or a line per chunk: S_E, mode shares, env steps/s

``begin(method, env_step)`` is where a resumed run drops what the files hold past the
checkpoint it restarts from (and a half-written last line), so that a resumed run's files are
those of a run that never stopped.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import uuid

import numpy as np

from nonmono_jax.core import hierarchy
from nonmono_jax.host import folder, rows as rows_lib


@contextlib.contextmanager
def closing(sinks):
  """The sinks for the block, every one closed however it ends (the first error wins)."""
  with contextlib.ExitStack() as stack:
    for sink in sinks:
      stack.callback(sink.close)
    yield sinks


class MetricsCsv:
  """``metrics.csv`` (``rows.MetricsFile``): rows flushed to disk before the chunk's checkpoint.
  Given the run's ``plan``, a resume also checks that the rows up to the checkpoint are one
  per seed and chunk (``rows.check_rows``)."""

  def __init__(self, out: str, plan=None):
    self.file = rows_lib.MetricsFile(os.path.join(out, "metrics.csv"))
    self.plan = plan

  def begin(self, method: str, env_step: int) -> None:
    if self.plan is not None and env_step:  # before anything is dropped: refused untouched
      spec, num_envs = self.plan.spec, self.plan.configs[method].num_envs
      rows_lib.check_rows(self.file.path, method, env_step, spec.seeds, spec.chunk * num_envs)
    self.file.truncate(method, env_step)

  def write(self, result) -> None:
    self.file.append(result.rows)

  def close(self) -> None:
    pass


class JsonLines:
  """``metrics.jsonl``: per seed and chunk, the row's columns and every metric of the chunk
  (whatever keys ``train.reduce_chunk`` returns; a vector metric as a list)."""

  def __init__(self, out: str):
    self.path = os.path.join(out, "metrics.jsonl")

  def begin(self, method: str, env_step: int) -> None:
    if not os.path.exists(self.path):
      return
    with open(self.path) as f:
      text = f.read()
    keep = []
    for line in text.splitlines(keepends=True):
      try:
        record = json.loads(line)
      except ValueError:
        continue  # a half-written line (a kill while writing it)
      if line.endswith("\n") and not (record.get("method") == method
                                      and record.get("env_step", 0) > env_step):
        keep.append(line)
    folder.write_text(self.path, "".join(keep))

  def write(self, result) -> None:
    with open(self.path, "a") as f:
      for row in result.rows:
        seed = row["seed"]
        values = {name: np.asarray(v)[seed].tolist() for name, v in result.metrics.items()}
        f.write(json.dumps({**row, "step": result.step, **values}) + "\n")
      f.flush()
      os.fsync(f.fileno())

  def close(self) -> None:
    pass


def log_line(*parts, **_) -> None:
  """``print`` (flushed), above the progress bar when one is drawn (``tqdm.write``)."""
  from tqdm import tqdm
  tqdm.write(" ".join(str(p) for p in parts))
  sys.stdout.flush()


def scalars(result) -> dict:
  """A chunk's scalars by name, as TensorBoard and W&B take them: the mean over seeds of every
  numeric column and every metric (a vector metric per component, ``name/i``), and S_E per
  seed (``eval_success/seed<k>``)."""
  rows, out = result.rows, {}
  for col in rows_lib.COLUMNS[4:]:
    values = [r[col] for r in rows if r[col] != ""]
    if values:
      out[col] = sum(values) / len(values)
  for name, value in result.metrics.items():
    mean = np.asarray(value, dtype=np.float64).mean(axis=0)
    for i, v in np.ndenumerate(mean):
      out[name + "".join(f"/{j}" for j in i)] = float(v)
  for r in rows:
    if r["eval_success"] != "":
      out[f"eval_success/seed{r['seed']}"] = r["eval_success"]
  return out


# The optional loggers' packages, and how to get them (``check_available``).
OPTIONAL = {"tensorboard": ("tensorboardX", "pip install 'nonmono-jax[tensorboard]'"),
            "wandb": ("wandb", "pip install 'nonmono-jax[wandb]'")}


def check_available(flag: str) -> None:
  """A ValueError (one line, before the run starts) if ``--<flag>``'s package is missing."""
  module, how = OPTIONAL[flag]
  try:
    __import__(module)
  except ImportError:
    raise ValueError(f"--{flag} needs the {module} package: {how}") from None


class TensorBoard:
  """Event files per method (``scalars``): the mean over seeds of every numeric column and
  every metric, and S_E per seed."""

  def __init__(self, out: str):
    self.out, self.writer = out, None

  def begin(self, method: str, env_step: int) -> None:
    self.close()
    from tensorboardX import SummaryWriter  # the [tensorboard] extra (check_available)
    self.writer = SummaryWriter(os.path.join(self.out, "tensorboard", method))

  def write(self, result) -> None:
    for name, value in scalars(result).items():
      self.writer.add_scalar(name, value, result.env_step)
    self.writer.flush()

  def close(self) -> None:
    if self.writer is not None:
      self.writer.close()
      self.writer = None


class WandB:
  """Weights & Biases: one W&B run per method (variant) in ``project``, grouped by the run
  folder, with the method's config and the run's size as its config, and per chunk the
  TensorBoard sink's scalars (``scalars``) at the env step. With ``WANDB_MODE=offline`` (no
  account, no network) it writes ``OUT/wandb/offline-run-*`` only (``wandb sync`` uploads
  them). A resumed run continues the same W&B runs (their ids in ``OUT/wandb/ids.json``); W&B
  drops a value logged at a step it has passed, so chunks redone after a resume keep the
  values first logged for them (metrics.csv is the record that a resume makes exact)."""

  def __init__(self, plan, project: str):
    import wandb  # the [wandb] extra (check_available)
    self.wandb, self.plan, self.project, self.runs = wandb, plan, project, {}
    self.folder = os.path.join(plan.out, "wandb")

  def _id(self, method: str) -> str:
    """The W&B run id of ``method``, made once per run folder and kept there."""
    path = os.path.join(self.folder, "ids.json")
    ids = folder.read_json(path) if os.path.exists(path) else {}
    if method not in ids:
      ids[method] = uuid.uuid4().hex[:8]  # W&B's id format: 8 of [a-z0-9]
      os.makedirs(self.folder, exist_ok=True)
      folder.write_json(path, ids)
    return ids[method]

  def begin(self, method: str, env_step: int) -> None:
    if method in self.runs:
      return
    plan = self.plan
    config = {"task": plan.task, "method": method, "preset": plan.preset, "seed": plan.seed,
              "run": folder.to_jsonable(plan.spec),
              "agent": folder.to_jsonable(plan.configs[method])}
    self.runs[method] = self.wandb.init(
        project=self.project, id=self._id(method), resume="allow", dir=plan.out,
        name=f"{os.path.basename(os.path.abspath(plan.out))}/{method}",
        group=os.path.basename(os.path.abspath(plan.out)), job_type=plan.task, config=config,
        reinit="create_new")

  def write(self, result) -> None:
    self.runs[result.method].log(scalars(result), step=result.env_step)

  def close(self) -> None:
    runs, self.runs = self.runs, {}
    for r in runs.values():
      r.finish()


class Progress:
  """A tqdm bar per method with the latest S_E, the last chunk's mode shares and env steps/s;
  without the bar (``enabled=False``) the same as one line per chunk through ``log``."""

  def __init__(self, plan, enabled: bool = True, log=print):
    self.plan, self.enabled, self.log, self.bar = plan, enabled, log, None
    self.group: list = []  # the variants the bar follows (one program)

  def begin(self, method: str, env_step: int) -> None:
    if method in self.group:  # a later variant of the bar's program
      return
    self.close()
    self.group = next((g for g in self.plan.groups() if method in g), [method])
    if self.enabled:
      from tqdm import tqdm
      num_envs = self.plan.configs[method].num_envs
      desc = method if len(self.group) == 1 else f"{len(self.group)} variants in one program"
      self.bar = tqdm(total=self.plan.spec.steps, initial=env_step // num_envs,
                      desc=f"{self.plan.task} {desc}", unit="step", dynamic_ncols=True,
                      smoothing=0.1)

  def write(self, result) -> None:
    rows = result.rows
    s_e = sum(r["eval_success"] or 0.0 for r in rows) / len(rows)
    shares = {m: sum(r[f"steps_{m}"] for r in rows) for m in hierarchy.MODES}
    total = max(sum(shares.values()), 1)
    status = (f"S_E {s_e:.2f} | " + " ".join(f"{m} {shares[m] / total:.0%}"
                                              for m in hierarchy.MODES)
              + ("" if math.isnan(result.rate) else f" | {result.rate:.0f} env/s"))
    if self.bar is not None:
      self.bar.set_postfix_str(status if len(self.group) == 1 else f"{result.method}: {status}",
                               refresh=False)
      if result.method == self.group[-1]:
        self.bar.update(self.plan.spec.chunk)
    else:
      self.log(f"{result.method} step {result.step}/{self.plan.spec.steps}: {status}")

  def close(self) -> None:
    self.group = []
    if self.bar is not None:
      self.bar.close()
      self.bar = None
