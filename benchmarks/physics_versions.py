"""MuJoCo 2.x against MuJoCo 3 on HIRO's literal AntPush and AntFall: record, then compare.

The paper's code ran MuJoCo 2.0. ``record``, run under a MuJoCo 2.x of its own venv (2.3.7 is
the nearest to 2.0 that pip installs on Python 3.11; never a project dependency), writes what
the literal models (``envs.ant.ant_maze_xml(layout, optimised=False)``) do as fixtures;
``compare``, run under the project's MuJoCo 3, plays the same scenarios with each contact
setting (``envs.contacts``) and prints the distances:

    python3 -m venv /work/venv-mj2 && /work/venv-mj2/bin/pip install mujoco==2.3.7 numpy
    /work/venv-mj2/bin/python benchmarks/physics_versions.py record \\
        tests/data/physics_mujoco2.npz
    python -m benchmarks.physics_versions compare tests/data/physics_mujoco2.npz

Scenarios, each on AntPush and AntFall unless said (an env step is 5 RK4 steps of 0.02 s):

* ``rest``: the ant from ``qpos0``, zero torques, 2 s: torso position and quaternion per step.
* ``torques``: ``SEQUENCES`` seeded random-torque sequences (uniform in +-30) of ``STEPS`` env
  steps from HIRO's reset noise: torso xyz (float64) and ``qpos[:15]`` (float32) per step.
* ``force``: the block pushed by a constant force on its body (``xfrc_applied``) after 1 s at
  rest; Push: -x (free floor towards cell (2, 1)) and +x / +y (the task's way, scraping the
  walls' corners); Fall: +y for 3 s, then let go for 3 s (it reaches its limit over the chasm
  and drops). The block's joint positions per step.
* ``gait`` (Push): the ant walking into the block with a fixed sinusoidal gait for 30 s, from
  ``GAIT_RUNS`` seeded resets: torso xyz and the block's joints per step (float32). Chaotic once
  the ant meets the block: compare its statistics, not its paths.

MuJoCo 2.3.3-2.3.7 have a collision midphase that ignored geom margins (fixed in 3.0.0; 2.0
had no midphase): ``record`` switches it off, which makes 2.3.7 bit-identical to 2.3.2 (the
last release without it) on these scenarios; ``--keep-midphase`` records 2.3.7 as it is.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import pathlib
import sys
import types

import mujoco
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
TASKS = ("Push", "Fall")
SEQUENCES = 6
STEPS = 300  # env steps of a random-torque sequence: 30 s
N_FRAMES = 5
REST_STEPS = 20
SETTLE_STEPS = 10
PUSH_FORCES = {"x-2": (0, -2.0, 20), "x-5": (0, -5.0, 20), "x-10": (0, -10.0, 20),
               "x+5": (0, 5.0, 30), "x+20": (0, 20.0, 30), "y+5": (1, 5.0, 30)}
FALL_FORCES = {"y+0.5": (1, 0.5, 30), "y+1": (1, 1.0, 30), "y+2": (1, 2.0, 30)}
FALL_RELEASE_STEPS = 30
GAIT_STEPS = 300
GAIT_RUNS = 6
GAIT_PHASE = np.array([0, 2, 3, 4, 2, 3, 2, 3]) * np.pi / 2
GAIT_PERIOD = 8  # env steps


def builders():
  """``envs.ant``, ``envs.contacts`` and ``envs.maze``; under MuJoCo 2.x (no JAX or MJX to
  import ``envs`` itself) loaded without the package's ``__init__``."""
  if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
  try:
    import envs  # noqa: F401  (the project's package: JAX, MJX)
  except ImportError:
    package = types.ModuleType("envs")
    package.__path__ = [str(ROOT / "envs")]
    sys.modules["envs"] = package
  from envs import ant, contacts, maze
  return ant, contacts, maze


def literal_xml(task: str) -> str:
  """HIRO's literal model of ``task`` as this MuJoCo reads it (2.x has no ``ls_iterations``
  option: its line search always stops at 50, HIRO_SOLVER's value)."""
  ant, _, maze = builders()
  xml = ant.ant_maze_xml(maze.MAZES[task].layout(8.0), optimised=False)
  if mujoco.__version__.startswith("2."):
    xml = xml.replace(f' ls_iterations="{ant.HIRO_SOLVER.ls_iterations}"', "")
  return xml


def xml_digest(task: str) -> str:
  """sha256 of the literal model's XML as MuJoCo 3 reads it (what the fixtures were made of)."""
  ant, _, maze = builders()
  xml = ant.ant_maze_xml(maze.MAZES[task].layout(8.0), optimised=False)
  return hashlib.sha256(xml.encode()).hexdigest()


def load(task: str, contacts: str | None = None, midphase: bool = True) -> mujoco.MjModel:
  """The literal model of ``task``; on MuJoCo 3 with ``contacts`` applied, on 2.x without the
  2.3.3-2.3.7 midphase unless ``midphase``."""
  model = mujoco.MjModel.from_xml_string(literal_xml(task))
  if contacts is not None:
    builders()[1].apply_contacts(model, contacts)
  if not midphase and hasattr(mujoco.mjtDisableBit, "mjDSBL_MIDPHASE"):
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
  return model


# --- the scenarios --------------------------------------------------------------------------

def _block(model) -> tuple[int, np.ndarray]:
  """The block's body id and its joints' qpos addresses."""
  body = next(b for b in range(model.nbody) if model.body_jntnum[b]
              and model.body_rootid[b] == b and model.jnt_type[model.body_jntadr[b]] == 2)
  joints = range(model.body_jntadr[body], model.body_jntadr[body] + model.body_jntnum[body])
  return body, np.array([model.jnt_qposadr[j] for j in joints])


def _step(model, data, ctrl=None, force=None, body=None):
  """One env step: ``N_FRAMES`` mj_step with ``ctrl`` held and ``force`` on ``body``."""
  data.ctrl[:] = 0.0 if ctrl is None else ctrl
  data.xfrc_applied[:] = 0.0
  if force is not None:
    data.xfrc_applied[body, :3] = force
  for _ in range(N_FRAMES):
    mujoco.mj_step(model, data)


def rest(model) -> np.ndarray:
  """(REST_STEPS, 7) torso position and quaternion, zero torques from ``qpos0``."""
  data, out = mujoco.MjData(model), []
  for _ in range(REST_STEPS):
    _step(model, data)
    out.append(data.qpos[:7].copy())
  return np.array(out)


def resets(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
  """HIRO's reset noise, seeded: (n, 15) on the ant's qpos, (n, 14) its qvel."""
  rng = np.random.default_rng(seed)
  return rng.uniform(-0.1, 0.1, (n, 15)), 0.1 * rng.normal(size=(n, 14))


def torque_inputs(task: str, sequences: int = SEQUENCES) -> tuple:
  """Seeded (controls (S, T, 8) float32, reset qpos noise (S, 15), qvel noise (S, 14))."""
  rng = np.random.default_rng(TASKS.index(task))
  ctrl = rng.uniform(-30, 30, (sequences, STEPS, 8)).astype(np.float32)
  return (ctrl, *resets(100 + TASKS.index(task), sequences))


def _reset(model, dq, dv):
  data = mujoco.MjData(model)
  data.qpos[:15] += dq
  data.qvel[:14] = dv
  return data


def torques(model, ctrl, dq, dv) -> np.ndarray:
  """(T, 15) ant ``qpos[:15]`` after each env step of ``ctrl`` from the reset ``dq``, ``dv``."""
  data, out = _reset(model, dq, dv), []
  for c in ctrl:
    _step(model, data, c)
    out.append(data.qpos[:15].copy())
  return np.array(out)


def force(model, axis: int, newtons: float, steps: int, release: int = 0) -> np.ndarray:
  """(steps + release, n) block joint positions: ``newtons`` along ``axis`` on the block body
  after ``SETTLE_STEPS`` at rest, then ``release`` steps without."""
  body, qadr = _block(model)
  data, out = mujoco.MjData(model), []
  for _ in range(SETTLE_STEPS):
    _step(model, data)
  push = np.zeros(3)
  push[axis] = newtons
  for k in range(steps + release):
    _step(model, data, force=push if k < steps else None, body=body)
    out.append(data.qpos[qadr].copy())
  return np.array(out)


def gait(model, dq, dv) -> tuple[np.ndarray, np.ndarray]:
  """(GAIT_STEPS, 3) torso xyz and (GAIT_STEPS, 2) block joints, the ant walking into it from
  the reset ``dq``, ``dv``."""
  _, qadr = _block(model)
  data, xyz, blk = _reset(model, dq, dv), [], []
  for t in range(GAIT_STEPS):
    _step(model, data, 30 * np.sin(2 * np.pi * t / GAIT_PERIOD + GAIT_PHASE))
    xyz.append(data.qpos[:3].copy())
    blk.append(data.qpos[qadr].copy())
  return np.array(xyz), np.array(blk)


def forces(task: str) -> dict:
  """The block force levels of ``task``: name -> (axis, newtons, steps, release steps)."""
  if task == "Push":
    return {k: (*v, 0) for k, v in PUSH_FORCES.items()}
  return {k: (*v, FALL_RELEASE_STEPS) for k, v in FALL_FORCES.items()}


def measure(task: str, model, sequences: int = SEQUENCES) -> dict:
  """Every scenario of ``task`` on ``model``: fixture key -> array."""
  out = {f"{task}/rest": rest(model)}
  ctrl, dq, dv = torque_inputs(task, sequences)
  runs = np.array([torques(model, c, q, v) for c, q, v in zip(ctrl, dq, dv)])
  out[f"{task}/torques_xyz"] = runs[..., :3]
  out[f"{task}/torques_qpos"] = runs.astype(np.float32)
  for name, (axis, newtons, steps, release) in forces(task).items():
    out[f"{task}/force_{name}"] = force(model, axis, newtons, steps, release)
  if task == "Push":
    runs = [gait(model, q, v) for q, v in zip(*resets(200, GAIT_RUNS))]
    out["Push/gait_xyz"] = np.array([r[0] for r in runs], np.float32)
    out["Push/gait_block"] = np.array([r[1] for r in runs], np.float32)
  return out


# --- record ---------------------------------------------------------------------------------

def record(path: str, keep_midphase: bool, sequences: int = SEQUENCES) -> None:
  """Write the fixtures of this MuJoCo (2.x) to ``path`` with their metadata."""
  arrays = {}
  for task in TASKS:
    arrays.update(measure(task, load(task, midphase=keep_midphase), sequences))
  meta = {"mujoco": mujoco.__version__, "numpy": np.__version__,
          "midphase": keep_midphase or not hasattr(mujoco.mjtDisableBit, "mjDSBL_MIDPHASE"),
          "command": " ".join([pathlib.Path(sys.executable).name, *sys.argv]),
          "date": datetime.date.today().isoformat(),
          "xml_sha256": {task: xml_digest(task) for task in TASKS},
          "sequences": sequences, "steps": STEPS}
  np.savez_compressed(path, meta=json.dumps(meta), **arrays)
  print(f"wrote {path} ({pathlib.Path(path).stat().st_size // 1024} KB), MuJoCo "
        f"{mujoco.__version__}")


def load_fixtures(path: str) -> tuple[dict, dict]:
  """(metadata, arrays) of a fixture file."""
  with np.load(path) as f:
    arrays = {k: f[k] for k in f.files if k != "meta"}
    return json.loads(str(f["meta"])), arrays


# --- compare --------------------------------------------------------------------------------

def settings() -> dict:
  """The MuJoCo 3 settings compared: name -> a function applying it to a compiled model."""
  contacts = builders()[1]

  def margins_and_invweight(model):
    contacts.halve_margins(model)
    contacts.legacy_invweight(model)

  return {"mujoco3": lambda model: None, "margins/2": contacts.halve_margins,
          "margins/2 + invweight": margins_and_invweight,
          "mujoco2": lambda model: contacts.apply_contacts(model, "mujoco2"),
          "mujoco200": lambda model: contacts.apply_contacts(model, "mujoco200")}


def torso_errors(measured: dict, fixture: dict, task: str) -> np.ndarray:
  """(S, T) distance between the torso paths of the random-torque sequences."""
  key = f"{task}/torques_xyz"
  return np.linalg.norm(measured[key] - fixture[key], axis=-1)


def block_ratio(measured: dict, fixture: dict, key: str, step: int = -1) -> float:
  """Block displacement along the pushed joint at ``step``, measured / fixture."""
  axis = int(np.argmax(np.abs(fixture[key][step] - fixture[key][0])))
  moved = lambda run: run[step, axis] - run[0, axis]
  return float(moved(measured[key]) / moved(fixture[key]))


def drop_step(run: np.ndarray) -> int:
  """The first env step at which the Fall block is 1 below its platform (-1: never)."""
  down = np.nonzero(run[:, -1] < -1.0)[0]
  return int(down[0]) if down.size else -1


def rows(measured: dict, fixture: dict) -> dict:
  """Distances of one setting's run from the fixtures: row name -> value (text)."""
  out = {}
  for task in TASKS:
    z = measured[f"{task}/rest"][-1, 2] - fixture[f"{task}/rest"][-1, 2]
    out[f"Ant{task}: rest height after 2 s, difference (mm)"] = f"{1000 * z:+.2f}"
    err = torso_errors(measured, fixture, task)
    for t, label in ((9, "1 s"), (99, "10 s"), (299, "30 s")):
      out[f"Ant{task}: torso error at {label}, median / max of {len(err)}"] = (
          f"{np.median(err[:, t]):.1e} / {err[:, t].max():.1e}")
    out[f"Ant{task}: sequences within 1 mm for 30 s"] = f"{(err.max(1) < 1e-3).sum()}/{len(err)}"
  for name in PUSH_FORCES:
    steps = PUSH_FORCES[name][2]
    out[f"Push block, {name} N for {steps / 10:g} s: displacement ratio"] = (
        f"{block_ratio(measured, fixture, f'Push/force_{name}'):.3f}")
  for name in FALL_FORCES:
    key = f"Fall/force_{name}"
    dy = measured[key][FALL_FORCES[name][2] - 1, 0] - fixture[key][FALL_FORCES[name][2] - 1, 0]
    drop = (drop_step(measured[key]), drop_step(fixture[key]))
    out[f"Fall block, {name} N: y at 3 s, difference (mm); drop step (vs 2.x)"] = (
        f"{1000 * dy:+.1f}; {drop[0]} ({drop[1]})")
  gait_err = np.linalg.norm(measured["Push/gait_xyz"] - fixture["Push/gait_xyz"], axis=-1)
  out[f"Push gait x {GAIT_RUNS}: torso error at 3 s, max; at 30 s, median"] = (
      f"{gait_err[:, 29].max():.1e}; {np.median(gait_err[:, -1]):.2f}")
  moved = lambda runs: np.linalg.norm(runs[:, -1] - runs[:, 0], axis=-1)
  out["Push gait: block moved in 30 s, mean (2.x)"] = (
      f"{moved(measured['Push/gait_block']).mean():.2f} "
      f"({moved(fixture['Push/gait_block']).mean():.2f})")
  return out


def compare(path: str) -> None:
  """Print the markdown table of every setting's distances from the fixtures at ``path``."""
  meta, fixture = load_fixtures(path)
  for task in TASKS:
    if meta["xml_sha256"][task] != xml_digest(task):
      print(f"warning: Ant{task}'s literal XML changed since the fixtures were recorded")
  table = {}
  for name, apply in settings().items():
    measured = {}
    for task in TASKS:
      model = load(task)
      apply(model)
      measured.update(measure(task, model, meta["sequences"]))
    table[name] = rows(measured, fixture)
  names = list(table)
  print(f"MuJoCo {mujoco.__version__} against {meta['mujoco']} (midphase "
        f"{'on' if meta['midphase'] else 'off'}), {path}\n")
  print("| | " + " | ".join(names) + " |")
  print("|---" * (len(names) + 1) + "|")
  for row in table[names[0]]:
    print(f"| {row} | " + " | ".join(table[n][row] for n in names) + " |")


def main(argv=None) -> None:
  p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
  sub = p.add_subparsers(dest="command", required=True)
  r = sub.add_parser("record", help="write this MuJoCo's (2.x) fixtures")
  r.add_argument("path")
  r.add_argument("--keep-midphase", action="store_true",
                 help="record 2.3.3-2.3.7 with their midphase (which ignored geom margins)")
  r.add_argument("--sequences", type=int, default=SEQUENCES,
                 help=f"random-torque sequences per task (default {SEQUENCES}, the tests')")
  c = sub.add_parser("compare", help="distances of MuJoCo 3's settings from the fixtures")
  c.add_argument("path")
  args = p.parse_args(argv)
  if args.command == "record":
    record(args.path, args.keep_midphase, args.sequences)
  else:
    compare(args.path)


if __name__ == "__main__":
  main()
