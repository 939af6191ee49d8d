"""The registry of envs by name: ``envs.make("AntPush")``, ``envs.NAMES`` (loads every robot)."""

from __future__ import annotations

import dataclasses

from envs import quiet  # noqa: F401 - before brax: mujoco.mjx's import prints nothing

from envs import maze
from envs.ant_maze import AntConfig, AntMazeEnv
from envs.point_maze import PointConfig, PointMazeEnv

_ROBOTS = {"Ant": (AntMazeEnv, AntConfig), "Point": (PointMazeEnv, PointConfig)}
NAMES = tuple(f"{robot}{task}" for robot in _ROBOTS for task in maze.MAZES)


def valid_overrides(name: str) -> tuple[str, ...]:
  """The keyword overrides ``make`` accepts for an env name."""
  _, config_cls = _ROBOTS[_split(name)[0]]
  return tuple(f.name for f in dataclasses.fields(config_cls))


def _split(name: str) -> tuple[str, str]:
  for robot in _ROBOTS:
    if name.startswith(robot) and name[len(robot):] in maze.MAZES:
      return robot, name[len(robot):]
  raise ValueError(f"unknown env {name!r}; valid names: {', '.join(NAMES)}")


def has_physics(name: str) -> bool:
  """Whether the env of ``name`` has a physics choice (``AntConfig.physics``: the ant on MuJoCo
  C or MJX); the point robot's physics is its own pure JAX."""
  return "physics" in valid_overrides(name)


def make(name: str, **overrides):
  """Build an env by name (``envs.NAMES``) with config overrides (``valid_overrides``)."""
  robot, task = _split(name)
  env_cls, config_cls = _ROBOTS[robot]
  valid = valid_overrides(name)
  unknown = sorted(set(overrides) - set(valid))
  if unknown:
    raise ValueError(f"unknown override(s) {unknown} for {name}; valid: {', '.join(valid)}")
  return env_cls(maze.MAZES[task], config_cls(**overrides))
