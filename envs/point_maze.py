"""PointPush, PointFall and PointMaze: a point mass in the same maze grids, in pure JAX.

The cheap robot for learning on a CPU. HIRO's PointMaze family uses maze scaling 4 and a point
of radius 0.5 that moves up to one unit per step; here it is holonomic: the action (2, in
[-1, 1]) is the xy displacement of the step. Everything else follows the ant tasks:

* the same grids through ``envs.maze`` (walls, platforms, chasm, movable blocks), with
  targets and success radius scaled by 4/8 and z kept a torso height (0.5) above the floor;
* observation ``[x, y, z, vx, vy, vz, t * 0.001]`` (position first, like the ant's, so the
  agent's goals are xyz offsets for either robot; velocities are per step);
* walls and blocks stop the point (axis-aligned sweeps: x first, then y; the point's
  footprint is its 1 x 1 bounding square); the point pushes a block along the axes the block's
  joints allow, as far as walls, platforms and the joint limits let it;
* a block whose footprint leaves every platform drops to the chasm floor, its top then flush
  with the platforms (a bridge); a point whose centre is over an unbridged chasm cell falls
  to the ground and stays in the trench (platform sides become walls).
"""

from __future__ import annotations

import dataclasses

from envs import quiet  # noqa: F401 - before brax: mujoco.mjx's import prints nothing
import jax
import jax.numpy as jp
import mujoco
import numpy as np
from brax.envs import base as brax_base
from flax import struct

from envs import base, maze

SCALING = 4.0
RADIUS = 0.5
OBS_SIZE = 7
ACTION_SIZE = 2
_EPS = 1e-5


@dataclasses.dataclass(frozen=True)
class PointConfig(base.EnvConfig):
  """Point maze options."""

  max_step: float = 1.0  # largest displacement per step along each axis

  def __post_init__(self):
    super().__post_init__()
    if self.max_step <= 0:
      raise ValueError(f"max_step must be positive, got {self.max_step}")


@struct.dataclass
class PointPhysics:
  """The point's physical state: centre, last displacement, block offsets from rest."""

  pos: jax.Array  # (3,) world centre
  vel: jax.Array  # (3,) displacement of the last step
  blocks: jax.Array  # (n_blocks, 3) offsets from the resting centre


class PointMazeEnv(base.MazeTask, brax_base.Env):
  """A point robot in a maze (brax ``Env`` interface, no physics engine)."""

  def __init__(self, spec: maze.Maze, config: PointConfig = PointConfig()):
    self.config = config
    self.maze = spec
    self.layout = lay = spec.layout(SCALING)
    self.target = jp.asarray(spec.scaled_target(SCALING), jp.float32)
    self.success_radius = spec.success_radius * SCALING / 8.0
    self.mj_model = mujoco.MjModel.from_xml_string(point_maze_xml(lay))
    self._top = lay.floor_z  # surface the point starts on
    self._start = np.array([0.0, 0.0, self._top + RADIUS], np.float32)
    walls, _ = lay.wall_boxes(optimised=True)
    plats = lay.platform_boxes(optimised=True)
    self._walls = _aabbs(walls)
    self._plats = _aabbs(plats)
    blocks = lay.blocks()
    self._block_rest = jp.asarray([b.box.center for b in blocks], jp.float32).reshape(-1, 3)
    self._block_half = jp.asarray([b.box.half for b in blocks], jp.float32).reshape(-1, 3)
    lo = np.full((len(blocks), 3), 0.0, np.float32)
    hi = np.full((len(blocks), 3), 0.0, np.float32)
    for n, b in enumerate(blocks):
      for ax, (a, c) in zip(b.axes, b.limits):
        k = "xyz".index(ax)
        lo[n, k], hi[n, k] = a, c
    self._block_lo, self._block_hi = jp.asarray(lo), jp.asarray(hi)
    self._n_blocks = len(blocks)
    chasm = lay.chasm_cells()
    self._chasm = _aabbs([lay.rect_box((i, j, i, j), 0.0, 0.0) for i, j in chasm])

  @property
  def observation_size(self) -> int:
    return OBS_SIZE

  @property
  def action_size(self) -> int:
    return ACTION_SIZE

  @property
  def action_limit(self) -> float:
    return 1.0

  @property
  def backend(self) -> str:
    return "jax"

  @property
  def dt(self) -> float:
    return 1.0

  def reset(self, rng: jax.Array) -> base.MazeState:
    k1, k2 = jax.random.split(rng)
    s = self.config.reset_noise_scale
    pos = jp.asarray(self._start).at[:2].add(jax.random.uniform(k1, (2,), minval=-s, maxval=s))
    vel = jp.zeros(3).at[:2].set(s * jax.random.normal(k2, (2,)))
    ps = PointPhysics(pos=pos, vel=vel, blocks=jp.zeros((self._n_blocks, 3)))
    return self._state(ps, jp.zeros((), jp.int32))

  def step(self, state: base.MazeState, action: jax.Array) -> base.MazeState:
    ps = state.pipeline_state
    delta = self.config.max_step * jp.clip(action, -1.0, 1.0)
    pos, blocks = ps.pos, ps.blocks
    for k in (0, 1):  # x, then y
      pos, blocks = self._move_axis(pos, blocks, delta[k], k)
    blocks = self._drop_unsupported_blocks(blocks)
    pos = self._fall(pos, blocks)
    ps = PointPhysics(pos=pos, vel=pos - ps.pos, blocks=blocks)
    return self._state(ps, state.steps + 1)

  def _state(self, ps: PointPhysics, steps) -> base.MazeState:
    return self.make_state(ps, jp.concatenate([ps.pos, ps.vel]), ps.pos, steps)

  # --- kinematics --------------------------------------------------------------------------

  def _fallen(self, z: jax.Array) -> jax.Array:
    return z < self._top - _EPS

  def _static(self, z: jax.Array):
    """Obstacles at height z: walls always, platforms only below their top (in the trench)."""
    lo = jp.concatenate([self._walls[0], self._plats[0]])
    hi = jp.concatenate([self._walls[1], self._plats[1]])
    active = jp.concatenate([jp.ones(self._walls[0].shape[0], bool),
                             jp.full(self._plats[0].shape[0], self._fallen(z))])
    return lo, hi, active

  def _block_boxes(self, blocks: jax.Array):
    c = self._block_rest + blocks
    return c - self._block_half, c + self._block_half

  def _move_axis(self, pos, blocks, d, k):
    """Move the point by d along axis k, pushing blocks the joints let move."""
    p_lo, p_hi = pos[:2] - RADIUS, pos[:2] + RADIUS
    s_lo, s_hi, s_on = self._static(pos[2])
    for n in range(self._n_blocks):
      b_lo, b_hi = self._block_boxes(blocks)
      # A block is in the point's way if its top is above the point's bottom.
      in_level = b_hi[n, 2] > pos[2] - RADIUS + _EPS
      want = jp.where(d > 0, p_hi[k] + d - b_lo[n, k], p_lo[k] + d - b_hi[n, k])
      ahead = jp.where(d > 0, b_lo[n, k] >= p_hi[k] - _EPS, b_hi[n, k] <= p_lo[k] + _EPS)
      touch = _overlap(p_lo, p_hi, b_lo[n], b_hi[n], 1 - k) & in_level & ahead
      push = jp.where(touch & (d != 0) & ((d > 0) == (want > 0)), want, 0.0)
      # Joint limits, then walls (and other blocks) in the block's path.
      push = jp.clip(push, self._block_lo[n, k] - blocks[n, k], self._block_hi[n, k] - blocks[n, k])
      others = jp.arange(self._n_blocks) != n
      o_lo = jp.concatenate([s_lo, b_lo[:, :2]])
      o_hi = jp.concatenate([s_hi, b_hi[:, :2]])
      o_on = jp.concatenate([self._static(b_hi[n, 2] - _EPS)[2], others])
      push = _sweep(b_lo[n, :2], b_hi[n, :2], push, k, o_lo, o_hi, o_on)
      blocks = blocks.at[n, k].add(push)
    b_lo, b_hi = self._block_boxes(blocks)
    b_on = b_hi[:, 2] > pos[2] - RADIUS + _EPS
    o_lo = jp.concatenate([s_lo, b_lo[:, :2]])
    o_hi = jp.concatenate([s_hi, b_hi[:, :2]])
    o_on = jp.concatenate([s_on, b_on])
    d = _sweep(p_lo, p_hi, d, k, o_lo, o_hi, o_on)
    return pos.at[k].add(d), blocks

  def _drop_unsupported_blocks(self, blocks):
    """Blocks free to fall (a z joint) drop to their limit once no platform is beneath."""
    if not self.layout.elevated or self._n_blocks == 0:
      return blocks
    b_lo, b_hi = self._block_boxes(blocks)
    p_lo, p_hi = self._plats
    support = jax.vmap(lambda lo, hi: jp.any(jax.vmap(
        lambda a, b: _overlap2(lo, hi, a, b))(p_lo, p_hi)))(b_lo[:, :2], b_hi[:, :2])
    can_fall = self._block_lo[:, 2] < 0
    return blocks.at[:, 2].set(jp.where(can_fall & ~support, self._block_lo[:, 2],
                                        blocks[:, 2]))

  def _fall(self, pos, blocks):
    """A point on top whose centre is over an unbridged chasm cell falls to the ground."""
    if not self.layout.elevated:
      return pos
    c_lo, c_hi = self._chasm
    over_chasm = jp.any(jp.all((pos[:2] >= c_lo) & (pos[:2] <= c_hi), axis=-1))
    b_lo, b_hi = self._block_boxes(blocks)
    bridged = jp.any(jp.all((pos[:2] >= b_lo[:, :2]) & (pos[:2] <= b_hi[:, :2]), axis=-1)
                     & (b_hi[:, 2] >= self._top - _EPS))
    falls = over_chasm & ~bridged & ~self._fallen(pos[2])
    return pos.at[2].set(jp.where(falls, RADIUS, pos[2]))

  # --- rendering ---------------------------------------------------------------------------

  def qpos(self, state: base.MazeState) -> jax.Array:
    """Joint positions of ``mj_model`` (point x, y, z offsets, then block offsets)."""
    ps = state.pipeline_state
    parts = [ps.pos - jp.asarray(self._start)]
    for n, blk in enumerate(self.layout.blocks()):
      parts.append(jp.stack([ps.blocks[n, "xyz".index(a)] for a in blk.axes]))
    return jp.concatenate(parts)

  def block_positions(self, state: base.MazeState) -> jax.Array:
    return self._block_rest + state.pipeline_state.blocks


def _aabbs(boxes: list[maze.Box]):
  lo = np.array([b.lo[:2] for b in boxes], np.float32).reshape(-1, 2)
  hi = np.array([b.hi[:2] for b in boxes], np.float32).reshape(-1, 2)
  return jp.asarray(lo), jp.asarray(hi)


def _overlap(a_lo, a_hi, b_lo, b_hi, j):
  return (a_hi[j] > b_lo[j] + _EPS) & (a_lo[j] < b_hi[j] - _EPS)


def _overlap2(a_lo, a_hi, b_lo, b_hi):
  return _overlap(a_lo, a_hi, b_lo, b_hi, 0) & _overlap(a_lo, a_hi, b_lo, b_hi, 1)


def _sweep(lo, hi, d, k, o_lo, o_hi, on):
  """Clamp a move of box [lo, hi] by d along axis k at the first obstacle in its path."""
  j = 1 - k
  side = (hi[j] > o_lo[:, j] + _EPS) & (lo[j] < o_hi[:, j] - _EPS) & on
  gap_pos = jp.where(side & (o_lo[:, k] >= hi[k] - _EPS), o_lo[:, k] - hi[k], jp.inf)
  gap_neg = jp.where(side & (o_hi[:, k] <= lo[k] + _EPS), o_hi[:, k] - lo[k], -jp.inf)
  return jp.clip(d, jp.minimum(jp.max(gap_neg, initial=-jp.inf), 0.0),
                 jp.maximum(jp.min(gap_pos, initial=jp.inf), 0.0))


def point_maze_xml(layout: maze.MazeLayout) -> str:
  """MJCF of the maze with a point body, for rendering the pure-JAX rollouts."""
  z = layout.floor_z + RADIUS
  ext = max(layout.shape) * layout.scaling
  return f"""<mujoco model="point_maze">
  <visual><global offwidth="640" offheight="480"/></visual>
  <asset>
    <texture builtin="checker" height="100" name="texplane" rgb1="0 0 0" rgb2="0.8 0.8 0.8"
             type="2d" width="100"/>
    <material name="MatPlane" reflectance="0.2" texrepeat="30 30" texture="texplane"/>
  </asset>
  <worldbody>
    <light directional="true" diffuse="1 1 1" dir="0 0 -1" pos="0 0 20"/>
    <geom name="floor" type="plane" size="{ext:g} {ext:g} 40" material="MatPlane"
          rgba="0.8 0.9 0.8 1"/>
    {maze.maze_worldbody_xml(layout, True, (1, 1), (1, 1))}
    <body name="point" pos="0 0 {z:g}">
      <joint name="point_x" type="slide" axis="1 0 0" limited="false"/>
      <joint name="point_y" type="slide" axis="0 1 0" limited="false"/>
      <joint name="point_z" type="slide" axis="0 0 1" limited="false"/>
      <geom name="point" type="sphere" size="{RADIUS:g}" rgba="0.8 0.4 0.1 1"/>
    </body>
  </worldbody>
</mujoco>"""
