"""A run as a library: make or load its plan, hold its folder, train its methods chunk by chunk.

    from nonmono_jax.host import run, sinks
    plan = run.new_run("PointMaze", ["ours"], preset="quick", out="runs/pm")  # or run.load_run(dir)
    with run.open_folder(plan):                                # created, locked, config.json
      outputs = [sinks.MetricsCsv(plan.out), sinks.JsonLines(plan.out)]
      with sinks.closing(outputs):
        for result in run.run_method(plan, "ours", outputs):  # one ChunkResult per chunk
          print(result.env_step, result.metrics["low/critic_loss"])

``run_method`` follows one method of the plan: restore the newest checkpoint that restores
(or init), ``begin`` every sink at that step, then per chunk: train (``trainer.chunk``), stop on
a NaN or Inf in a learner (``NonFinite``, the last checkpoint is the last good state), write
the rows to every sink, checkpoint (the rows are on disk first), yield. A ``Clock`` with a
time limit stops it before a chunk that would end past the limit (``TimeLimit``, checkpointed),
after at least one chunk per process. ``run_plan`` runs every method of the plan in turn.
``use_cpu_devices(n)``, called before JAX runs anything, splits the lanes over n CPU devices.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time

import jax
import numpy as np

from nonmono_jax.core.config import differences
from nonmono_jax.host import folder, interrupts, processes, rows as rows_lib, runlock
from nonmono_jax.host.checkpoints import Checkpoints
from nonmono_jax.host.interrupts import Terminated  # noqa: F401 - SIGTERM, as Ctrl-C
from nonmono_jax.host.programs import Programs
from nonmono_jax.host.plan import Plan, load_run, new_run  # noqa: F401 - the run's library entry points


class NonFinite(RuntimeError):
  """A NaN or Inf in a learner's parameters or losses, or a physics step that MuJoCo found
  unstable (names the steps, seed and where)."""


class TimeLimit(RuntimeError):
  """Stopped before a chunk that would end past the time limit (says what is checkpointed)."""


class BadFolder(ValueError):
  """A run folder that cannot be created or continued."""


@dataclasses.dataclass
class ChunkResult:
  method: str
  step: int  # vector steps reached
  env_step: int  # env steps reached (step x num_envs)
  rows: list  # metrics.csv's rows, one per seed (rows.chunk_rows)
  metrics: dict  # every metric of the chunk: name -> per-seed array (train.reduce_chunk)
  states: object  # the train state after the chunk (donated by the next chunk: do not keep)
  seconds: float  # wall time of the chunk
  rate: float  # env steps/s over all seeds since this process's first chunk (nan on it)


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
        first = float(folder.read_json(path)["first_chunk_s"])
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
        folder.write_json(self.path, {"first_chunk_s": seconds})

  def allows(self, chunk_s: float | None) -> bool:
    if self.deadline is None:
      return True
    estimate = self.first_chunk_s if chunk_s is None else chunk_s
    return time.monotonic() + estimate <= self.deadline


# --- the process: its CPU devices -----------------------------------------------------------

def use_cpu_devices(n: int) -> None:
  """Split a run's lanes over ``n`` CPU devices (``jax_num_cpu_devices``; the trainer shards
  its lanes over ``jax.devices()``, ``train.py``): one per core lets the cores run lanes side
  by side, where one device leaves the second core mostly idle (``benchmarks/cpu_profile.md``:
  on 2 cores, 16 seeds 1.6-2.5x faster than on one device). The lanes per device change how
  XLA:CPU rounds, so a run on 2 devices does not match the same run on 1 bit for bit. Call it
  before JAX runs anything; a ValueError if JAX has already started with another count."""
  if n < 1:
    raise ValueError(f"--cpu-devices must be >= 1, got {n}")
  try:
    jax.config.update("jax_num_cpu_devices", n)
  except RuntimeError:  # the backends are up: fine if they already have n CPU devices
    have = len(jax.devices("cpu"))
    if have != n:
      raise ValueError(f"--cpu-devices {n}: JAX has already started with {have} CPU "
                       f"device(s); set it before any JAX operation") from None


# --- the run folder ------------------------------------------------------------------------------

@contextlib.contextmanager
def open_folder(plan: Plan, resume: bool = False):
  """Creates (a new run) and locks (``runlock``) the run folder for the block; a new run's
  must be empty and gets ``config.json``, a resumed one must be complete. Raises BadFolder,
  runlock.Locked or rows.MetricsError."""
  if not processes.writer():  # process 0 of a multi-process run owns the folder
    processes.barrier("run folder open")
    yield plan
    return
  _check_path(plan.out)
  if not resume:
    check_new_out(plan.out)
  with contextlib.ExitStack() as stack:
    with interrupts.writing():  # a Ctrl-C waits for the folder and its config.json
      try:
        os.makedirs(plan.out, exist_ok=resume)
      except FileExistsError:
        pass  # an empty folder: checked below with the lock held
      except OSError as e:
        raise BadFolder(f"--out {plan.out}: cannot create the folder ({e.strerror})") from None
      try:
        stack.enter_context(runlock.hold(plan.out))
      except OSError as e:
        raise BadFolder(f"{plan.out}: cannot lock the run folder ({e.strerror})") from None
      _check_folder(plan, resume)
    processes.barrier("run folder open")
    yield plan


def new_or_continued(plan: Plan) -> tuple[Plan, bool]:
  """(plan, resume): ``plan`` as new, or the run its folder already holds if that is the same
  run (task, seed, size, physics, every variant's config), to continue: a notebook run twice
  picks up where it stopped (a finished run trains nothing more) instead of failing. A
  folder that holds another run is a BadFolder naming the first difference."""
  if not os.path.exists(os.path.join(plan.out, "config.json")):
    return plan, False
  saved = load_run(plan.out, task=plan.task)
  mine = {"task": plan.task, "seed": plan.seed, "spec": plan.spec, "physics": plan.physics,
          "contacts": plan.contacts, "variants": list(plan.configs)}
  theirs = {"task": saved.task, "seed": saved.seed, "spec": saved.spec,
            "physics": saved.physics, "contacts": saved.contacts,
            "variants": list(saved.configs)}
  differ = [k for k in mine if mine[k] != theirs[k]] + [
      f"{name} {', '.join(differences(plan.configs[name], saved.configs[name]))}"
      for name in plan.configs if name in saved.configs
      and plan.configs[name] != saved.configs[name]]
  if differ:
    raise BadFolder(f"{plan.out} holds another run (it differs in {differ[0]}): choose another "
                    f"folder, or remove that one")
  return saved, True


def check_new_out(out: str) -> None:
  """A new run's folder is absent or empty (a lock alone: a start that failed); else BadFolder
  saying how to continue the run it holds."""
  if not os.path.lexists(out):
    return
  if not os.path.isdir(out):
    raise BadFolder(f"--out {out} exists and is not a folder")
  if set(os.listdir(out)) - {runlock.NAME}:
    raise BadFolder(f"--out {out} exists and is not empty (use --resume {out} to continue it, "
                    f"or another --out)")


def _check_path(out: str) -> None:
  """A path the system can hold, checked before any of its folders is made."""
  path = os.path.abspath(out)
  name_max = os.pathconf("/", "PC_NAME_MAX") if hasattr(os, "pathconf") else 255
  long = [p for p in path.split(os.sep) if len(p.encode()) > name_max]
  if long:
    raise BadFolder(f"--out: the name {long[0][:40]}... is longer than {name_max} bytes")
  if len(path.encode()) >= 4096:
    raise BadFolder(f"--out: the path is {len(path.encode())} bytes long, more than the 4095 "
                    f"a path may have")


def _check_folder(plan: Plan, resume: bool) -> None:
  """With the lock held: a new run's folder is still empty; a resumed one is complete."""
  if not resume:
    if set(os.listdir(plan.out)) - {runlock.NAME}:
      raise BadFolder(f"--out {plan.out} was filled by another process meanwhile")
    try:
      folder.write_json(os.path.join(plan.out, "config.json"), folder.to_json(plan))
    except OSError as e:
      raise BadFolder(f"{plan.out}/config.json: cannot be written ({e.strerror})") from None
    _add_session(plan.out, resumed=False)
    return
  metrics = os.path.join(plan.out, "metrics.csv")
  ckpts = os.path.join(plan.out, "checkpoints")
  if os.path.lexists(ckpts) and not os.path.isdir(ckpts):
    raise BadFolder(f"{ckpts} is not a folder (move it away: the run keeps its checkpoints "
                    f"there)")
  if not os.path.exists(metrics) and os.path.isdir(ckpts) and os.listdir(ckpts):
    raise BadFolder(f"{metrics} is missing while checkpoints exist: the rows before them "
                    f"would be lost (put it back, or start a new run)")
  if os.path.exists(metrics):
    rows_lib.good_lines(metrics)  # raises MetricsError naming the file
  _add_session(plan.out, resumed=True)


def _add_session(out: str, resumed: bool) -> None:
  try:
    folder.add_session(out, resumed)
  except OSError as e:
    raise BadFolder(f"{out}/{folder.SESSIONS}: cannot be written ({e.strerror})") from None


# --- training ------------------------------------------------------------------------------------

def run_plan(plan: Plan, outputs, clock: Clock | None = None, log=print,
             programs: Programs | None = None) -> None:
  """Every group of the plan's variants (``Plan.groups``), one after another (each continues
  from its checkpoints); variants that share a program run as its lanes. ``programs``: the
  plan's trainers, if already built (the memory check's)."""
  clock, programs = clock or Clock(), programs or Programs(plan)
  for group in plan.groups():
    for _ in run_group(plan, group, outputs, clock, log, programs):
      pass


def run_method(plan: Plan, method: str, outputs=(), clock: Clock | None = None, log=print,
               programs: Programs | None = None):
  """Trains one variant alone (a group of one); see ``run_group``."""
  return run_group(plan, [method], outputs, clock, log, programs)


def run_group(plan: Plan, names, outputs=(), clock: Clock | None = None, log=print,
              programs: Programs | None = None):
  """Trains the variants ``names`` (one static key) as one program from their newest common
  checkpoint to ``plan.spec.steps``, writing every chunk to ``outputs`` (sinks) and yielding
  one ChunkResult per variant and chunk; see the module doc. Each variant keeps its own
  checkpoints (its lanes: the shape of a run of it alone), rows and sink files."""
  spec, names = plan.spec, list(names)
  trainer = (programs or Programs(plan)).trainer(names)
  clock = clock or Clock()
  ckpts = [Checkpoints(os.path.join(plan.out, "checkpoints", n), writer=processes.writer())
           for n in names]
  if len(names) > 1:
    log(f"{', '.join(names)}: one program, {len(names)} variants x {spec.seeds} seeds = "
        f"{trainer.num_lanes} lanes")
  try:
    yield from _train(plan, names, trainer, ckpts, outputs, clock, log)
  finally:
    for c in ckpts:
      c.close()


def _train(plan: Plan, names, trainer, ckpts, outputs, clock: Clock, log):
  """``run_group``'s loop: restore, then chunk by chunk (an exchange with a lost process of a
  multi-process run raises ``processes.ProcessLost``)."""
  spec, num_envs = plan.spec, plan.configs[names[0]].num_envs
  with processes.lost_peers():
    start, states = _start(plan, names, trainer, ckpts, outputs, log)
    timing = _Timing()
    for t0 in range(start, spec.steps, spec.chunk):
      # At least one chunk per process: a limit shorter than start-up + a chunk still advances.
      if processes.agree(not clock.allows(timing.chunk_s) and clock.progressed):
        raise TimeLimit("; ".join(_stop_for_time(plan, n, c, t0, trainer.lanes(states, v))
                                  for v, (n, c) in enumerate(zip(names, ckpts))))
      states, results = _chunk(plan, names, trainer, states, t0, ckpts, timing)
      step = t0 + spec.chunk
      with interrupts.writing():  # a Ctrl-C waits for the chunk's rows and checkpoint
        for result in results:
          for sink in outputs:
            sink.write(result)
        if step % spec.checkpoint_every == 0 or step == spec.steps:
          for v, c in enumerate(ckpts):
            c.save(step, trainer.lanes(states, v))
      clock.progressed = True
      timing.chunk_done(clock, spec.chunk * trainer.num_lanes * num_envs)
      pace = timing.pace_line(plan, names, t0)
      if pace:
        log(pace)
      interrupts.check()
      yield from results


def _start(plan: Plan, names, trainer, ckpts, outputs, log):
  """(step, states) to train from: restored (``_restore``), every sink begun there, and the
  chunk compiled ahead of its first call, saying so and how long it took (init, restore and
  compile); nothing compiled when the run is already at its end."""
  label, spec = ", ".join(names), plan.spec
  if not all((c.latest_step() or 0) >= spec.steps for c in ckpts):
    log(f"{label}: compiling the training program ...")
  t = time.monotonic()
  start, states = _restore(trainer, names, ckpts, plan.seed, log)
  if start:
    log(f"{label}: resumed from step {start}")
  for name in names:
    for sink in outputs:
      sink.begin(name, start * plan.configs[name].num_envs)
  if start >= spec.steps:
    log(f"{label}: already trained to step {start}, the run's end")
    return start, states
  cached = compile_chunk(trainer, states, start)
  log(f"{label}: compiled in {duration(time.monotonic() - t)}"
      + (" (from the compilation cache)" if cached else ""))
  interrupts.check()
  return start, states


def _restore(trainer, names, ckpts, seed: int, log):
  """(step, lanes) from each variant's newest checkpoint that restores; variants whose newest
  differ (a stop between their saves) all restart from the oldest of them."""
  fresh = trainer.init(jax.random.PRNGKey(seed))
  found = [c.restore_newest(trainer.lanes(fresh, v), log, move_aside=processes.writer())
           for v, c in enumerate(ckpts)]
  start = min(step or 0 for step, _ in found)
  if len(names) == 1:
    return start, found[0][1]
  parts = []
  for v, (c, (step, state)) in enumerate(zip(ckpts, found)):
    if (step or 0) != start:
      log(f"{names[v]}: back to step {start}, the step its group's other variants reached")
      if processes.writer():
        c.set_aside_after(start, log)
      processes.barrier(f"{names[v]} set aside")
      state = c.restore(start, trainer.lanes(fresh, v)) if start else trainer.lanes(fresh, v)
    parts.append(state)
  return start, jax.tree.map(lambda *xs: jax.numpy.concatenate(xs), *parts)


def compile_chunk(trainer, states, t0: int) -> bool:
  """Compiles the trainer's chunk for ``states`` ahead of its first call (which then runs the
  compiled program); whether XLA's persistent cache had it."""
  hits = []
  listener = lambda event, **kwargs: hits.append(1) if event.endswith("/cache_hits") else None
  jax.monitoring.register_event_listener(listener)
  try:
    trainer.compile(states, t0)
  finally:
    jax.monitoring.unregister_event_listener(listener)
  return bool(hits)


@dataclasses.dataclass
class _Timing:
  """A method's chunk times in this process: the latest chunk's wall time (for the clock,
  checkpoint included) and the env steps/s since the first chunk (which compiles)."""

  t_chunk: float = 0.0
  chunk_s: float | None = None
  t_start: float | None = None
  steps_done: int = 0
  said: tuple = ()  # the kinds of chunk whose pace was said: "warm-up", "training"

  def chunk_done(self, clock: Clock, env_steps: int) -> None:
    self.chunk_s = time.monotonic() - self.t_chunk
    if self.t_start is None:
      clock.saw_first_chunk(self.chunk_s)
      self.t_start = time.perf_counter()
    else:
      self.steps_done += env_steps

  def pace_line(self, plan: Plan, names, t0: int) -> str | None:
    """After the first chunk of its kind (warm-up, training) in this process: the time to the
    end of the run at this chunk's pace, on this machine; None after the others."""
    spec, config = plan.spec, plan.configs[names[0]]
    kind = "warm-up" if t0 + spec.chunk <= config.warmup_steps else "training"
    if kind in self.said or self.chunk_s is None:
      return None
    self.said += (kind,)
    groups = plan.groups()
    later = len(groups) - 1 - next(i for i, g in enumerate(groups) if names[0] in g)
    per_run = -(-spec.steps // spec.chunk)
    left = -(-(spec.steps - t0 - spec.chunk) // spec.chunk) + later * per_run
    estimate = duration(left * self.chunk_s)
    if not left:
      return None
    head = (f"{', '.join(names)}: a {kind} chunk of {spec.chunk} steps took "
            f"{duration(self.chunk_s)}")
    if kind == "warm-up":
      return (f"{head} on this machine; the {left} chunks left take at least {estimate} "
              f"(training chunks, with updates, are slower: estimated again after the warm-up, "
              f"step {config.warmup_steps})")
    return f"{head}; the {left} chunks left: about {estimate} on this machine at this pace"


def duration(seconds: float) -> str:
  """A wall time as a reader takes it in: 45 s, 12 min, 3 h 20 min, 2 d 5 h."""
  s = max(int(round(seconds)), 0)
  if s < 100:
    return f"{s} s"
  if s < 100 * 60:
    return f"{round(s / 60)} min"
  h, m = divmod(round(s / 60), 60)
  if h < 48:
    return f"{h} h {m} min" if m else f"{h} h"
  d, h = divmod(h, 24)
  return f"{d} d {h} h" if h else f"{d} d"


def _chunk(plan: Plan, names, trainer, states, t0: int, ckpts, timing: _Timing):
  """One chunk from step ``t0``: (states, a ChunkResult per variant); raises NonFinite."""
  spec, num_envs = plan.spec, plan.configs[names[0]].num_envs
  timing.t_chunk = time.monotonic()
  states, metrics = trainer.chunk(states, t0)
  t_end = t0 + spec.chunk
  # waits for the chunk; every lane on every process
  summary = processes.gather(trainer.summarise(states, metrics))
  metrics = processes.gather(metrics)
  bad = first_non_finite(summary)
  what = "NaN or Inf in {}"
  if bad is None:
    bad, what = first_unstable(summary), "unstable physics (MuJoCo reset the simulation) in {}"
  if bad is not None:
    variant, seed = divmod(int(bad[0]), spec.seeds)
    last = ckpts[variant].latest_step()
    raise NonFinite(f"{names[variant]}: {what.format(bad[1])} of seed {seed} within steps "
                    f"{t0}-{t_end}; " + (f"the last good checkpoint is step {last}"
                                         if last is not None else
                                         "no checkpoint was saved before it"))
  seconds = time.monotonic() - timing.t_chunk
  rate = _rate_after(timing, spec.chunk * trainer.num_lanes * num_envs)
  results = []
  for v, name in enumerate(names):
    lanes, lane_metrics = trainer.lanes(states, v), trainer.lanes(metrics, v)
    rows = rows_lib.chunk_rows(plan.task, name, t_end * num_envs, trainer.lanes(summary, v),
                               spec.episode_length, t_end >= plan.configs[name].first_eval_steps)
    results.append(ChunkResult(method=name, step=t_end, env_step=t_end * num_envs, rows=rows,
                               metrics=lane_metrics, states=lanes, seconds=seconds, rate=rate))
  return states, results


def first_non_finite(summary) -> tuple[int, str] | None:
  """(lane, where) of the first NaN or Inf in a chunk's ``summary`` (gathered): a learner's
  parameters (its level's name), else a learner's metric (``metric <name>``); or None."""
  finite = {**summary.params_finite,
            **{f"metric {name}": ok for name, ok in summary.metrics_finite.items()}}
  for lane in range(np.shape(summary.reward)[0]):
    for where, ok in finite.items():
      if not ok[lane]:
        return lane, where
  return None


def first_unstable(summary) -> tuple[int, str] | None:
  """(lane, "training" or "evaluation") of the first lane whose env steps the physics found
  unstable in the chunk (``env.unstable``), or None."""
  for steps, where in ((summary.unstable_steps, "training"),
                       (summary.unstable_evaluation, "evaluation")):
    lanes = np.flatnonzero(np.asarray(steps) > 0)
    if lanes.size:
      return int(lanes[0]), where
  return None


def _rate_after(timing: _Timing, env_steps: int) -> float:
  """The rate shown for a chunk: env steps/s since the first chunk of the process, this one
  included (nan for the first)."""
  if timing.t_start is None:
    return float("nan")
  return (timing.steps_done + env_steps) / max(time.perf_counter() - timing.t_start, 1e-9)


def _stop_for_time(plan: Plan, method: str, ckpts: Checkpoints, t0: int, states) -> str:
  """Checkpoints step ``t0`` if it is not yet; the time-limit message (saying what is saved)."""
  if t0 and ckpts.latest_step() != t0:
    ckpts.save(t0, states)
  saved = "checkpointed" if t0 else "nothing of it run yet"
  return (f"{method}: stopped at step {t0} of {plan.spec.steps} for the time limit ({saved}); "
          f"continue with --resume {plan.out}")
