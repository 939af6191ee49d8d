"""The maze tasks: HIRO's grids, targets and success radius (docs/spec.md, section 1)."""

from __future__ import annotations

import dataclasses

from envs import maze

XY, YZ, r = maze.BLOCK_XY, maze.BLOCK_YZ, maze.ROBOT

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
class Task:
  """A maze task at HIRO's ant scale (scaling 8); point variants rescale it."""

  grid: tuple
  target: tuple[float, float, float]  # at scaling 8
  success_radius: float = 5.0  # at scaling 8

  def layout(self, scaling: float) -> maze.MazeLayout:
    return maze.MazeLayout(self.grid, scaling=scaling)

  def scaled_target(self, scaling: float) -> tuple[float, float, float]:
    """xy scale with the maze; z stays a torso height above the task's floor."""
    k = scaling / 8.0
    floor = maze.MazeLayout(self.grid, scaling=8.0).floor_z
    z = self.target[2] - floor + maze.MazeLayout(self.grid, scaling=scaling).floor_z
    return (self.target[0] * k, self.target[1] * k, z)


TASKS = {
    "Push": Task(PUSH_GRID, (0.0, 19.0, 0.5)),
    "Fall": Task(FALL_GRID, (0.0, 27.0, 4.5)),
    "Maze": Task(MAZE_GRID, (0.0, 16.0, 0.5)),
}
# Not a task: the same ant alone on a flat floor, the throughput reference.
FLAT = Task(FLAT_GRID, (0.0, 16.0, 0.5))
