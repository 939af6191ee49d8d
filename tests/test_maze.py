"""Maze geometry: grid -> boxes, and every cell's height probed by rays (MuJoCo C)."""

import mujoco
import numpy as np
import pytest

from envs import ant, maze, point_maze


def _probe_height(model, x, y, exclude_body=-1, top=30.0):
  """Height of the first surface under (x, y), by a ray cast straight down."""
  geomid = np.zeros(1, np.int32)
  data = mujoco.MjData(model)
  mujoco.mj_forward(model, data)
  dist = mujoco.mj_ray(model, data, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]),
                       None, 1, exclude_body, geomid)
  return top - dist


def _expected_height(layout, cell):
  h, z0 = layout.height, layout.floor_z
  return {maze.WALL: z0 + h, maze.FREE: z0, maze.ROBOT: z0, maze.CHASM: 0.0,
          maze.BLOCK_XY: z0 + h, maze.BLOCK_YZ: z0 + h}[cell]


def _models(task_name):
  task = maze.MAZES[task_name]
  yield "ant-hiro", task.layout(8.0), ant.load(task.layout(8.0), optimised=False)
  yield "ant-optimised", task.layout(8.0), ant.load(task.layout(8.0), optimised=True)
  lay = task.layout(point_maze.SCALING)
  yield "point", lay, mujoco.MjModel.from_xml_string(point_maze.point_maze_xml(lay))


@pytest.mark.parametrize("task_name", sorted(maze.MAZES))
def test_every_cell_height_by_ray(task_name):
  for build, layout, model in _models(task_name):
    robot = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                              "point" if build == "point" else "torso")
    for i, row in enumerate(layout.grid):
      for j, cell in enumerate(row):
        x, y = layout.cell_center(i, j)
        # Probe off the exact centre so that no seam between boxes hides a surface.
        got = _probe_height(model, x + 0.13 * layout.scaling, y - 0.11 * layout.scaling, robot)
        assert got == pytest.approx(_expected_height(layout, cell), abs=1e-4), (
            build, task_name, (i, j), cell)


def test_hiro_coordinates():
  """docs/spec.md, section 1: robot at the origin, Push block at (0, 8), Fall block at (8, 8)."""
  push = maze.MAZES["Push"].layout(8.0)
  assert push.cell_center(*push.robot_cell) == (0.0, 0.0)
  (blk,) = push.blocks()
  assert blk.box.center == (0.0, 8.0, 2.0) and blk.box.half == (4.0, 4.0, 2.0)
  assert blk.axes == ("x", "y") and blk.mass == 0.0002
  assert not push.elevated and push.height == 4.0
  fall = maze.MAZES["Fall"].layout(8.0)
  (blk,) = fall.blocks()
  assert fall.elevated and fall.floor_z == 4.0
  assert blk.box.center == (8.0, 8.0, 6.0)
  assert blk.box.half == pytest.approx((3.96, 3.96, 2.0))
  assert blk.axes == ("y", "z") and blk.limits == ((-8.0, 8.0), (-4.0, 0.0))
  assert blk.mass == 0.001
  assert sorted(fall.cell_center(i, j) for i, j in fall.chasm_cells()) == [(0.0, 16.0), (8.0, 16.0)]
  assert fall.cell_at(8.0, 16.0) == (3, 2)


def test_merge_cells_is_an_exact_disjoint_cover():
  rng = np.random.default_rng(0)
  for _ in range(50):
    mask = rng.random((6, 7)) < 0.6
    cover = np.zeros(mask.shape, int)
    for i0, j0, i1, j1 in maze.merge_cells(mask):
      cover[i0:i1 + 1, j0:j1 + 1] += 1
    np.testing.assert_array_equal(cover, mask.astype(int))


def test_optimised_build_has_fewer_colliding_boxes_and_same_surface():
  for name, task in maze.MAZES.items():
    layout = task.layout(8.0)
    hiro, opt = ant.load(layout, optimised=False), ant.load(layout, optimised=True)

    def colliding_static(m):
      return sum(1 for g in range(m.ngeom) if m.geom_bodyid[g] == 0
                 and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
                 and (m.geom_contype[g] or m.geom_conaffinity[g]))

    assert colliding_static(opt) < colliding_static(hiro), name
    assert len(ant.colliding_geoms(hiro)) == 13 and len(ant.colliding_geoms(opt)) == 9
    # Same solid: heights agree at random points (away from the ant).
    rng = np.random.default_rng(1)
    ti, tj = hiro.body("torso").id, opt.body("torso").id
    n, m = layout.shape
    lo = np.array(layout.cell_center(0, 0)) - 4
    hi = np.array(layout.cell_center(n - 1, m - 1)) + 4
    for x, y in rng.uniform(lo, hi, size=(200, 2)):
      if abs(x) < 1.5 and abs(y) < 1.5:
        continue
      assert _probe_height(hiro, x, y, ti) == pytest.approx(_probe_height(opt, x, y, tj), abs=1e-4)


def test_bad_grid_is_rejected():
  with pytest.raises(ValueError, match="robot"):
    maze.MazeLayout(((1, 0), (0, 1)))
  with pytest.raises(ValueError, match="unknown cells"):
    maze.MazeLayout(((1, "r"), (7, 1)))
  with pytest.raises(ValueError, match="rows differ"):
    maze.MazeLayout(((1, "r"), (1,)))
