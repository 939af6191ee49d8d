"""AntPush, AntFall and AntMaze: HIRO's ant in a maze, as a brax ``Env``.

Observation (30): ant ``qpos[:15]`` (xyz, quaternion, 8 joints), ``qvel[:14]`` and ``t * 0.001``.
Blocks are simulated but not observed. Actions are the 8 motor torques, clipped to +-30.
One env step is 5 physics steps of 0.02 s (RK4), i.e. 0.1 s.

Two physics run the same model (``AntConfig.physics``, an ``envs.physics.Physics`` built once
by the env): ``mjx``, brax's MJX pipeline, the accelerator path (``envs.mjx_physics``, the state
a brax MJX state); ``c`` (the default), MuJoCo's C engine called from inside the jitted step
(``envs.c_physics``, the state a ``CState``), 10-25x faster on a CPU. A run's ``--physics
auto`` is resolved by its plan (``plan.run_physics``: c on a CPU backend, mjx on an
accelerator), never here. Both states have ``qpos`` and ``qvel``; ``unstable(state)`` is 1.0
after a step that made the simulation unstable (MuJoCo's bad qpos/qvel/qacc warnings in C; a
NaN or Inf in MJX).

``AntConfig.contacts`` picks the engine's contact settings (``envs.contacts``), applied to the
compiled model before either physics is built on it: ``mujoco3`` (the default) as MuJoCo 3
compiles HIRO's model; ``mujoco2``, the settings that make MuJoCo 3 move the ant and the
blocks as MuJoCo 2.x does (measured against 2.3.7); ``mujoco200``, those and MuJoCo 2.0's
capsule inertia, what the paper's code ran (``docs/environments.md``, "MuJoCo 2 and 3").
"""

from __future__ import annotations

import dataclasses

from envs import quiet  # noqa: F401 - before brax: mujoco.mjx's import prints nothing
import jax
import jax.numpy as jp
import mujoco
from brax.envs import base as brax_base

from envs import ant, base, c_physics, maze, mjx_physics
from envs import contacts as contacts_lib
from envs.physics import ENGINES, Physics

N_FRAMES = 5
OBS_SIZE = 30
_ANT_NQ, _ANT_NV = 15, 14
ENGINE = {"c": c_physics.CPhysics, "mjx": mjx_physics.MjxPhysics}  # by AntConfig.physics


@dataclasses.dataclass(frozen=True)
class AntConfig(base.EnvConfig):
  """Ant maze options. ``optimised=False`` builds HIRO's model literally (slow in MJX).
  ``physics``: ``c`` or ``mjx`` (``envs.physics.ENGINES``).
  ``contacts``: the engine's settings, ``mujoco3``, ``mujoco2`` or ``mujoco200``
  (``envs.contacts``)."""

  physics: str = "c"
  contacts: str = contacts_lib.DEFAULT
  optimised: bool = True
  solver_iterations: int = ant.FAST_SOLVER.iterations
  solver_ls_iterations: int = ant.FAST_SOLVER.ls_iterations
  max_contact_points: int = ant.FAST_SOLVER.max_contact_points
  max_geom_pairs: int = ant.FAST_SOLVER.max_geom_pairs

  def __post_init__(self):
    super().__post_init__()
    if self.physics not in ENGINES:
      raise ValueError(f"physics must be one of {', '.join(ENGINES)}, got {self.physics!r} "
                       f"(a run's plan resolves auto: plan.run_physics)")
    if self.contacts not in contacts_lib.CONTACTS:
      raise ValueError(f"contacts must be one of {', '.join(contacts_lib.CONTACTS)}, "
                       f"got {self.contacts!r}")
    for name in ("solver_iterations", "solver_ls_iterations"):
      if getattr(self, name) < 1:
        raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
    for name in ("max_contact_points", "max_geom_pairs"):
      v = getattr(self, name)
      if v != -1 and v < 1:
        raise ValueError(f"{name} must be -1 (no cap) or >= 1, got {v}")

  def solver(self) -> ant.SolverSettings:
    if not self.optimised:
      return ant.HIRO_SOLVER
    return ant.SolverSettings(self.solver_iterations, self.solver_ls_iterations,
                              self.max_contact_points, self.max_geom_pairs)


class AntMazeEnv(base.MazeTask, brax_base.Env):
  """HIRO's ant in one of the maze layouts (``maze.MAZES``)."""

  def __init__(self, spec: maze.Maze, config: AntConfig = AntConfig()):
    self.config = config
    self.maze = spec
    self.layout = spec.layout(8.0)
    self.mj_model = ant.load(self.layout, config.optimised, config.solver())
    contacts_lib.apply_contacts(self.mj_model, config.contacts)
    self.target = jp.asarray(spec.target, jp.float32)
    self.success_radius = spec.success_radius
    self.engine: Physics = ENGINE[config.physics](self.mj_model, N_FRAMES)
    self._qpos0 = jp.asarray(self.mj_model.qpos0, jp.float32)
    self._nv = self.mj_model.nv

  @property
  def physics(self) -> str:
    return self.config.physics

  @property
  def backend(self) -> str:
    return self.config.physics

  @property
  def dt(self) -> float:
    return float(self.mj_model.opt.timestep) * N_FRAMES

  @property
  def observation_size(self) -> int:
    return OBS_SIZE

  @property
  def action_size(self) -> int:
    return ant.ACTION_SIZE

  @property
  def action_limit(self) -> float:
    return ant.CTRL_LIMIT

  def reset(self, rng: jax.Array) -> base.MazeState:
    """HIRO reset: qpos0 + U(-0.1, 0.1) and qvel 0.1 N(0, 1) on the ant; blocks exact."""
    k1, k2 = jax.random.split(rng)
    s = self.config.reset_noise_scale
    qpos = self._qpos0.at[:_ANT_NQ].add(
        jax.random.uniform(k1, (_ANT_NQ,), minval=-s, maxval=s))
    qvel = jp.zeros(self._nv).at[:_ANT_NV].set(s * jax.random.normal(k2, (_ANT_NV,)))
    ps = self.pipeline_init(qpos, qvel)
    return self._state(ps, jp.zeros((), jp.int32))

  def pipeline_init(self, q: jax.Array, qd: jax.Array):
    """The engine's state at ``q``, ``qd`` (a start the caller chose)."""
    return self.engine.init(q, qd)

  def step(self, state: base.MazeState, action: jax.Array) -> base.MazeState:
    action = jp.clip(action, -ant.CTRL_LIMIT, ant.CTRL_LIMIT)
    ps = self.engine.step(state.pipeline_state, action)
    return self._state(ps, state.steps + 1)

  def _state(self, ps, steps) -> base.MazeState:
    body = jp.concatenate([ps.qpos[:_ANT_NQ], ps.qvel[:_ANT_NV]])
    return self.make_state(ps, body, ps.qpos[:3], steps)

  def unstable(self, state: base.MazeState) -> jax.Array:
    return self.engine.unstable(state.pipeline_state)

  def qpos(self, state: base.MazeState) -> jax.Array:
    """Joint positions of ``mj_model`` for rendering."""
    return state.pipeline_state.qpos

  def block_positions(self, state: base.MazeState) -> jax.Array:
    """(n_blocks, 3) world centres of the movable blocks."""
    return block_centres(self.layout, self.mj_model, state.pipeline_state.qpos)


def block_centres(layout: maze.MazeLayout, model, qpos) -> jax.Array:
  """World centres of the blocks from the model's slide joints."""
  out = []
  for blk in layout.blocks():
    c = jp.asarray(blk.box.center, jp.float32)
    for k, ax in enumerate("xyz"):
      if ax in blk.axes:
        i, j = blk.cell
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"block_{ax}_{i}_{j}")
        c = c.at[k].add(qpos[model.jnt_qposadr[jid]])
    out.append(c)
  return jp.stack(out) if out else jp.zeros((0, 3))
