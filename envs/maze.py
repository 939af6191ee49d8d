"""HIRO's mazes (``MAZES``: grids, targets and success radius, docs/spec.md, section 1) and
their grids turned into MJCF: walls, platforms, chasm and movable blocks.

One place turns a grid into geometry, for every robot (the MJX ant and, for rendering, the
pure-JAX point). The layout follows HIRO's ``maze_env.py`` (Nachum et al. 2018): cell (i, j)
is centred at ``(j*s - torso_x, i*s - torso_y)`` so that the robot starts at the origin; walls
are ``maze_height * s`` high; an elevated maze (one with a chasm) puts a platform of that
height under every non-chasm cell and raises walls and blocks onto it.

Two builds of the same layout exist:

* ``optimised=False``: HIRO literally, one box per wall cell and per platform cell.
* ``optimised=True``: the same solid, with wall and platform cells merged into as few boxes as
  the layout allows, and wall cells that no robot can touch (no free cell among their eight
  neighbours) kept for rendering only. ``envs.ant`` decides which robot geoms collide.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence, Union

import numpy as np

Cell = Union[int, str]

WALL = 1
FREE = 0
CHASM = -1
ROBOT = "r"
BLOCK_XY = "XY"
BLOCK_YZ = "YZ"
_VALID_CELLS = (WALL, FREE, CHASM, ROBOT, BLOCK_XY, BLOCK_YZ)

# Contact bits (contype / conaffinity). A pair collides when one's contype meets the
# other's conaffinity. HIRO uses bit 0 everywhere; the optimised build splits the floor off
# so that blocks, which have no z freedom on the floor, do not grind on it.
BIT_STATIC = 1  # walls and platforms
BIT_FLOOR = 2  # the ground plane


@dataclasses.dataclass(frozen=True)
class Box:
  """An axis-aligned box: centre and half-sizes, in world coordinates."""

  center: tuple[float, float, float]
  half: tuple[float, float, float]

  @property
  def lo(self) -> np.ndarray:
    return np.asarray(self.center) - np.asarray(self.half)

  @property
  def hi(self) -> np.ndarray:
    return np.asarray(self.center) + np.asarray(self.half)


@dataclasses.dataclass(frozen=True)
class Block:
  """A movable block: its cell, the axes it slides along and their limits (offsets)."""

  cell: tuple[int, int]
  box: Box  # at rest
  axes: tuple[str, ...]  # subset of ("x", "y", "z")
  limits: tuple[tuple[float, float], ...]  # per axis; (-inf, inf) when unlimited
  mass: float


@dataclasses.dataclass(frozen=True)
class MazeLayout:
  """A maze grid (rows top to bottom, docs/spec.md section 1 legend) and its scaling."""

  grid: tuple[tuple[Cell, ...], ...]
  scaling: float = 8.0
  maze_height: float = 0.5

  def __post_init__(self):
    rows = {len(r) for r in self.grid}
    if len(rows) != 1:
      raise ValueError(f"grid: rows differ in length {sorted(rows)}")
    cells = [c for r in self.grid for c in r]
    bad = [c for c in cells if c not in _VALID_CELLS]
    if bad:
      raise ValueError(f"grid: unknown cells {bad}; valid: {_VALID_CELLS}")
    if cells.count(ROBOT) != 1:
      raise ValueError("grid: needs exactly one robot cell 'r'")

  @property
  def shape(self) -> tuple[int, int]:
    return len(self.grid), len(self.grid[0])

  @property
  def height(self) -> float:
    """Wall (and platform) height: maze_height * scaling."""
    return self.maze_height * self.scaling

  @property
  def elevated(self) -> bool:
    """HIRO elevates the maze when it has a chasm (AntFall)."""
    return any(c == CHASM for r in self.grid for c in r)

  @property
  def floor_z(self) -> float:
    """Height of the surface the robot starts on."""
    return self.height if self.elevated else 0.0

  @property
  def robot_cell(self) -> tuple[int, int]:
    for i, row in enumerate(self.grid):
      for j, c in enumerate(row):
        if c == ROBOT:
          return i, j
    raise AssertionError("unreachable")

  def cell_center(self, i: int, j: int) -> tuple[float, float]:
    ri, rj = self.robot_cell
    s = self.scaling
    return (j - rj) * s, (i - ri) * s

  def cell_at(self, x: float, y: float) -> tuple[int, int]:
    """The (row, col) of the cell containing world point (x, y)."""
    ri, rj = self.robot_cell
    s = self.scaling
    return int(np.floor(y / s + 0.5)) + ri, int(np.floor(x / s + 0.5)) + rj

  def mask(self, *kinds: Cell) -> np.ndarray:
    return np.array([[c in kinds for c in row] for row in self.grid], dtype=bool)

  def rect_box(self, rect: tuple[int, int, int, int], z_lo: float, z_hi: float) -> Box:
    """Box covering cells rows i0..i1, cols j0..j1 (inclusive) between two heights."""
    i0, j0, i1, j1 = rect
    s = self.scaling
    x0, y0 = self.cell_center(i0, j0)
    x1, y1 = self.cell_center(i1, j1)
    return Box(
        center=((x0 + x1) / 2, (y0 + y1) / 2, (z_lo + z_hi) / 2),
        half=((x1 - x0 + s) / 2, (y1 - y0 + s) / 2, (z_hi - z_lo) / 2),
    )

  # --- what the maze is made of -------------------------------------------------------------

  def wall_boxes(self, optimised: bool) -> tuple[list[Box], list[Box]]:
    """(colliding walls, render-only walls) standing on the floor or the platforms."""
    walls = self.mask(WALL)
    z0 = self.floor_z
    if not optimised:
      return [self.rect_box((i, j, i, j), z0, z0 + self.height)
              for i, j in zip(*np.nonzero(walls))], []
    touch = walls & _dilate(~walls)
    solid = [self.rect_box(r, z0, z0 + self.height) for r in merge_cells(touch)]
    ghost = [self.rect_box(r, z0, z0 + self.height) for r in merge_cells(walls & ~touch)]
    return solid, ghost

  def platform_boxes(self, optimised: bool) -> list[Box]:
    """Platforms under every non-chasm cell of an elevated maze (none otherwise)."""
    if not self.elevated:
      return []
    cells = ~self.mask(CHASM)
    rects = merge_cells(cells) if optimised else [(i, j, i, j) for i, j in zip(*np.nonzero(cells))]
    return [self.rect_box(r, 0.0, self.height) for r in rects]

  def blocks(self) -> list[Block]:
    """Movable blocks as HIRO builds them (maze_env.py): XY slides freely, YZ can fall."""
    out = []
    s, z0 = self.scaling, self.floor_z
    for i, row in enumerate(self.grid):
      for j, c in enumerate(row):
        if c not in (BLOCK_XY, BLOCK_YZ):
          continue
        falling = "Z" in c
        shrink = 0.99 if falling else 1.0
        x, y = self.cell_center(i, j)
        box = Box((x, y, z0 + self.height / 2),
                  (0.5 * s * shrink, 0.5 * s * shrink, self.height / 2))
        axes, limits = [], []
        for ax in ("x", "y"):
          if ax.upper() in c:
            axes.append(ax)
            limits.append((-s, s) if falling else (-np.inf, np.inf))
        if falling:
          axes.append("z")
          limits.append((-z0, 0.0))
        out.append(Block((i, j), box, tuple(axes), tuple(limits),
                         mass=0.001 if falling else 0.0002))
    return out

  def chasm_cells(self) -> list[tuple[int, int]]:
    return [tuple(int(v) for v in ij) for ij in zip(*np.nonzero(self.mask(CHASM)))]


def _dilate(mask: np.ndarray) -> np.ndarray:
  """Cells with a True cell among their eight neighbours (or themselves)."""
  p = np.pad(mask, 1)
  n, m = mask.shape
  return np.any([p[1 + di:1 + di + n, 1 + dj:1 + dj + m]
                 for di in (-1, 0, 1) for dj in (-1, 0, 1)], axis=0)


def merge_cells(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
  """Cover the True cells of a grid with few disjoint rectangles (i0, j0, i1, j1).

  Greedy: from the first uncovered cell in reading order, extend right as far as possible,
  then down while the whole row span is uncovered. Exact cover, not always minimal.
  """
  todo = np.array(mask, dtype=bool)
  rects = []
  n, m = todo.shape
  for i in range(n):
    for j in range(m):
      if not todo[i, j]:
        continue
      j1 = j
      while j1 + 1 < m and todo[i, j1 + 1]:
        j1 += 1
      i1 = i
      while i1 + 1 < n and todo[i1 + 1, j:j1 + 1].all():
        i1 += 1
      todo[i:i1 + 1, j:j1 + 1] = False
      rects.append((i, j, i1, j1))
  return rects


def _fmt(v: Sequence[float]) -> str:
  return " ".join(f"{float(x):.6g}" for x in v)


def maze_worldbody_xml(layout: MazeLayout, optimised: bool, static_bits: tuple[int, int],
                       block_bits: tuple[int, int]) -> str:
  """MJCF for the maze: walls and platforms as world geoms, blocks as bodies.

  Args:
    layout: the maze.
    optimised: merge cells and drop untouchable walls from collision (see module doc).
    static_bits: (contype, conaffinity) of walls and platforms.
    block_bits: (contype, conaffinity) of movable blocks.
  """
  parts = []
  sc, sa = static_bits
  for k, b in enumerate(layout.platform_boxes(optimised)):
    parts.append(f'<geom name="platform_{k}" type="box" pos="{_fmt(b.center)}" '
                 f'size="{_fmt(b.half)}" contype="{sc}" conaffinity="{sa}" '
                 f'rgba="0.9 0.9 0.9 1"/>')
  solid, ghost = layout.wall_boxes(optimised)
  for k, b in enumerate(solid):
    parts.append(f'<geom name="wall_{k}" type="box" pos="{_fmt(b.center)}" '
                 f'size="{_fmt(b.half)}" contype="{sc}" conaffinity="{sa}" '
                 f'rgba="0.4 0.4 0.4 1"/>')
  for k, b in enumerate(ghost):
    parts.append(f'<geom name="wall_visual_{k}" type="box" pos="{_fmt(b.center)}" '
                 f'size="{_fmt(b.half)}" contype="0" conaffinity="0" '
                 f'rgba="0.4 0.4 0.4 1"/>')
  bc, ba = block_bits
  for blk in layout.blocks():
    i, j = blk.cell
    joints = []
    for ax, (lo, hi) in zip(blk.axes, blk.limits):
      axis = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}[ax]
      limited = np.isfinite(lo)
      rng = f' range="{lo:g} {hi:g}"' if limited else ""
      joints.append(f'<joint name="block_{ax}_{i}_{j}" type="slide" axis="{axis}" '
                    f'limited="{str(bool(limited)).lower()}"{rng} armature="0" '
                    f'damping="0" margin="0.01"/>')
    parts.append(
        f'<body name="block_{i}_{j}" pos="{_fmt(blk.box.center)}">'
        + "".join(joints)
        + f'<geom name="block_{i}_{j}" type="box" size="{_fmt(blk.box.half)}" '
        f'mass="{blk.mass:g}" contype="{bc}" conaffinity="{ba}" rgba="0.9 0.1 0.1 1"/>'
        + "</body>")
  return "\n".join(parts)


# --- HIRO's mazes -----------------------------------------------------------------------------

XY, YZ, r = BLOCK_XY, BLOCK_YZ, ROBOT

PUSH_GRID = ((1, 1, 1, 1, 1),
             (1, 0, r, 1, 1),
             (1, 0, XY, 0, 1),
             (1, 1, 0, 1, 1),
             (1, 1, 1, 1, 1))
FALL_GRID = ((1, 1, 1, 1),
             (1, r, 0, 1),
             (1, 0, YZ, 1),
             (1, -1, -1, 1),
             (1, 0, 0, 1),
             (1, 1, 1, 1))
MAZE_GRID = ((1, 1, 1, 1, 1),
             (1, r, 0, 0, 1),
             (1, 1, 1, 0, 1),
             (1, 0, 0, 0, 1),
             (1, 1, 1, 1, 1))
# The ant alone on a flat floor (the benchmark's reference): no walls that it can reach.
FLAT_GRID = ((r,),)


@dataclasses.dataclass(frozen=True)
class Maze:
  """One of HIRO's mazes at the ant's scale (scaling 8): its grid, the target and the success
  radius; the point robot rescales it. A task (``methods.TASKS``) is a robot in one of them."""

  grid: tuple
  target: tuple[float, float, float]  # at scaling 8
  success_radius: float = 5.0  # at scaling 8

  def layout(self, scaling: float) -> MazeLayout:
    return MazeLayout(self.grid, scaling=scaling)

  def scaled_target(self, scaling: float) -> tuple[float, float, float]:
    """xy scale with the maze; z stays a torso height above the task's floor."""
    k = scaling / 8.0
    floor = MazeLayout(self.grid, scaling=8.0).floor_z
    z = self.target[2] - floor + MazeLayout(self.grid, scaling=scaling).floor_z
    return (self.target[0] * k, self.target[1] * k, z)


MAZES = {
    "Push": Maze(PUSH_GRID, (0.0, 19.0, 0.5)),
    "Fall": Maze(FALL_GRID, (0.0, 27.0, 4.5)),
    "Maze": Maze(MAZE_GRID, (0.0, 16.0, 0.5)),
}
# Not a task's: the same ant alone on a flat floor, the throughput reference.
FLAT = Maze(FLAT_GRID, (0.0, 16.0, 0.5))
