"""Where one training step's time goes on XLA:CPU: a per-op profile of the jitted chunk.

Runs a chunk of the trainer (warm-up and starting mode 0, evaluation off, as
``train_throughput``) under ``jax.profiler``, then reads the trace back (``ProfileData``): XLA:CPU
records one event per executed thunk (a fusion, a dot, a copy, a loop), nested under its
``while`` / ``cond``. Each thunk's self time (its duration less its children's) is summed per
thunk and grouped two ways: by kind (``ynn_fusion`` = a dot run by YNNPACK, ``dot`` = Eigen,
``copy``, loop fusions ...) and by the JAX operation that made it (the op_name metadata in the
compiled HLO, e.g. ``MLP/dense_1/dot_general``), and by the agent's phase that ran it (the
gated functions of ``core/agent.py``: ``low_update``, ``middle_update``, ``middle_ppo_update``,
``end_segment``, ``end_horizon``, ``train`` (the Top), ``evaluation``, else ``step``: the env,
the physics callback, the buffers and the scan's own copies). Tracing adds about 1 us per thunk,
so the traced total exceeds the untimed step; the shares are what to read. With ``--repeats R``
each thunk keeps its least self time of R traced chunks: on a shared machine another process
only ever adds time.

    python -m benchmarks.profile_step --seeds 1 16                    # point preset, HIRO
    python -m benchmarks.profile_step --method ours --hidden 300 300 --seeds 16 --steps 20
    python -m benchmarks.profile_step --env AntPush --method ours --seeds 1 --steps 200 --repeats 3

Writes ``benchmarks/results/profile_step_<platform>_<date>.json`` and prints the tables.
"""

from __future__ import annotations

import argparse
import collections
import glob
import os
import re
import tempfile
import time

import jax
from jax.profiler import ProfileData

import envs
from benchmarks import common
from benchmarks.common import ALL_MODES_LIVE
from nonmono_jax.core import train
from nonmono_jax.host import methods

_STRIP = re.compile(r"jit\(local_chunk\)/|while/body/|closed_call/|vmap\(\)/|branch_\d_fun/"
                    r"|cond/|jvp\(|transpose\(|vmap\(|checkpoint/|\)")


def make_point_trainer(env_name, method, seeds, chunk, hidden=None):
  """The trainer of ``train_throughput`` at the task's preset (optionally other TD3 layers)."""
  env = envs.make(env_name, episode_length=100 if env_name.startswith("Point") else 1000)
  layers = {"low.hidden": tuple(hidden), "middle.hidden": tuple(hidden)} if hidden else {}
  config = common.paper_config(method, env_name, {**ALL_MODES_LIVE, **layers})
  return train.make_trainer(env, config, num_seeds=seeds, chunk_steps=chunk)


def thunk_self_times(xplane: str) -> dict:
  """{thunk name: [count, self ns]} over the XLA:CPU worker threads of a trace."""
  agg = collections.defaultdict(lambda: [0, 0])
  for plane in ProfileData.from_file(xplane).planes:
    for line in plane.lines:
      if not line.name.startswith("tf_XLA"):
        continue
      events = sorted(((e.start_ns, e.duration_ns, e.name) for e in line.events),
                      key=lambda e: (e[0], -e[1]))
      stack = []  # [end, name, children's ns, duration]

      def pop():
        _, name, child, dur = stack.pop()
        agg[name][0] += not name.startswith("end: ")  # an async thunk's end: no new op
        agg[name][1] += dur - child
      for start, dur, name in events:
        while stack and stack[-1][0] <= start:
          pop()
        if stack:
          stack[-1][2] += dur
        stack.append([start + dur, name, 0, dur])
      while stack:
        pop()
  for waiting in ("ThunkExecutor::Execute", "ThunkExecutor::Execute (wait for completion)"):
    agg.pop(waiting, None)  # the caller's wait for the program, no work of its own
  return dict(agg)


def op_names(hlo_text: str) -> dict:
  """{HLO instruction name: shortened JAX op_name} from the compiled module's metadata."""
  out = {}
  for m in re.finditer(r"^\s+(?:ROOT )?%([\w.\-]+) = .*?op_name=\"([^\"]*)\"", hlo_text, re.M):
    out[m.group(1)] = _STRIP.sub("", m.group(2))
  return out


# The agent's gated phases (``gates.gated`` jits each under its function's name), in the order
# of the paper's Algorithm 1; a thunk outside all of them is the step's own work.
PHASES = ("low_update", "middle_update", "middle_ppo_update", "end_segment", "end_horizon",
          "train", "evaluation")
_PHASE = re.compile(r"jit\((" + "|".join(PHASES) + r")\b")


def phases(hlo_text: str) -> dict:
  """{HLO instruction name: phase} for every instruction of the compiled module.

  An instruction's own op_name names its phase; one without (copies, YNNPACK's fused dots)
  takes its fused computation's phase, else the phase most of its enclosing computation's
  instructions carry, else "step"."""
  comp, where, own, calls = None, {}, {}, {}
  for line in hlo_text.splitlines():
    head = re.match(r"^(?:ENTRY )?%([\w.\-]+) .*\{$", line)
    if head:
      comp = head.group(1)
      continue
    m = re.match(r"^\s+(?:ROOT )?%([\w.\-]+) = ", line)
    if not m:
      continue
    where[m.group(1)] = comp
    phase = _PHASE.search(line)
    if phase:
      own[m.group(1)] = phase.group(1)
    called = re.search(r"calls=%([\w.\-]+)", line)
    if called:
      calls[m.group(1)] = called.group(1)
  votes = collections.defaultdict(collections.Counter)
  for name, phase in own.items():
    votes[where[name]][phase] += 1
  of_comp = {c: v.most_common(1)[0][0] for c, v in votes.items()}
  return {name: own.get(name) or of_comp.get(calls.get(name)) or of_comp.get(c) or "step"
          for name, c in where.items()}


def min_times(runs: list[dict]) -> dict:
  """Per thunk, the run with the least self time: another process's preemption only ever
  adds time, so on a shared machine the minimum over repeats is the cleanest reading."""
  out = {}
  for name in set().union(*runs):
    out[name] = min((r[name] for r in runs if name in r), key=lambda cn: cn[1])
  return out


def group(times: dict, key, steps: int, top: int) -> list[dict]:
  total = sum(ns for _, ns in times.values())
  acc = collections.defaultdict(lambda: [0, 0])
  for name, (count, ns) in times.items():
    k = key(name)
    acc[k][0] += count
    acc[k][1] += ns
  rows = sorted(acc.items(), key=lambda kv: -kv[1][1])[:top]
  return [{"name": k, "us_per_step": ns / steps / 1e3, "share": ns / total,
           "ops_per_step": c / steps} for k, (c, ns) in rows]


def profile(env_name, method, seeds, steps, hidden, top, repeats=1) -> dict:
  trainer = make_point_trainer(env_name, method, seeds, steps, hidden)
  states = trainer.init(jax.random.PRNGKey(0))
  compiled = common.compile_chunk(trainer, states)
  states, _ = jax.block_until_ready(compiled(states, 0))
  t0 = time.perf_counter()
  states, _ = jax.block_until_ready(compiled(states, steps))
  untraced = time.perf_counter() - t0
  runs = []
  for r in range(repeats):
    with tempfile.TemporaryDirectory() as d:
      jax.profiler.start_trace(d)
      states, _ = jax.block_until_ready(compiled(states, (2 + r) * steps))
      jax.profiler.stop_trace()
      runs.append(thunk_self_times(sorted(glob.glob(f"{d}/**/*.xplane.pb", recursive=True))[-1]))
  times = min_times(runs)
  text = compiled.as_text()
  names, phase_of = op_names(text), phases(text)
  kind = lambda n: re.sub(r"[.\d]+$", "", n.replace("end: ", ""))
  op = lambda n: names.get(n.replace("end: ", ""), "(" + kind(n) + ")")
  return {"env": env_name, "method": method, "seeds": seeds, "hidden": hidden,
          "load_average": os.getloadavg(),
          "steps": steps, "repeats": repeats,
          "untraced_ms_per_step": untraced / steps * 1e3,
          "traced_self_ms_per_step": sum(ns for _, ns in times.values()) / steps / 1e6,
          "thunks_per_step": sum(c for c, _ in times.values()) / steps,
          "by_phase": group(times, lambda n: phase_of.get(n.replace("end: ", ""), "(runtime)"),
                            steps, top),
          "by_phase_kind": group(times, lambda n: phase_of.get(n.replace("end: ", ""), "(runtime)")
                                 + " / " + kind(n), steps, top),
          "by_kind": group(times, kind, steps, top), "by_op": group(times, op, steps, top)}


def print_profile(r):
  print(f"\n{r['env']} {r['method']} seeds {r['seeds']} hidden {r['hidden'] or 'preset'}: "
        f"{r['untraced_ms_per_step']:.3f} ms/step untraced, {r['traced_self_ms_per_step']:.3f} "
        f"traced, {r['thunks_per_step']:.0f} thunks/step")
  for title in ("by_phase", "by_phase_kind", "by_kind", "by_op"):
    print(f"  {title}:")
    for row in r[title]:
      print(f"    {row['us_per_step']:9.1f} us/step {100 * row['share']:5.1f}% "
            f"{row['ops_per_step']:7.1f} ops/step  {row['name']}")


def main(argv=None):
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--env", default="PointPush")
  p.add_argument("--method", default="hiro", choices=methods.METHODS)
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 16])
  p.add_argument("--hidden", nargs="+", type=int, default=None,
                 help="Low and Middle TD3 layers (default: the task's preset)")
  p.add_argument("--steps", type=int, default=100, help="env steps in the traced chunk")
  p.add_argument("--top", type=int, default=20, help="rows per table")
  p.add_argument("--repeats", type=int, default=1,
                 help="traced chunks; each thunk's least self time is kept (a shared machine)")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  rows = []
  for s in args.seeds:
    rows.append(profile(args.env, args.method, s, args.steps, args.hidden, args.top,
                        args.repeats))
    print_profile(rows[-1])
  common.write_result("profile_step", args.out, argv, results=rows)


if __name__ == "__main__":
  main()
