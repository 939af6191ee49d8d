"""Maze environments: HIRO's Ant Push / Fall / Maze on MJX, and their pure-JAX point twins.

    import envs
    env = envs.make("AntPush", episode_length=500)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    state = jax.jit(env.step)(state, jp.zeros(env.action_size))
    state.success, state.distance, env.target, env.success_radius, env.mj_model

The package loads nothing heavy until it is used: ``envs.make`` and the names below import the
robots (JAX, MuJoCo, MJX) on first use, and a light module (``envs.physics``, ``envs.maze``)
imports alone, so that the experiment command answers ``--help`` without JAX.
"""

from __future__ import annotations

import importlib

_FROM = {"make": "registry", "NAMES": "registry", "valid_overrides": "registry",
         "has_physics": "registry", "AntMazeEnv": "ant_maze", "AntConfig": "ant_maze",
         "PointMazeEnv": "point_maze", "PointConfig": "point_maze", "EnvConfig": "base",
         "MazeEnv": "base", "MazeState": "base"}
__all__ = [*_FROM, "maze"]


def __getattr__(name: str):
  """A registry name from its module, or a submodule (``envs.maze``), imported on first use."""
  if name not in _FROM:
    try:
      return importlib.import_module(f"envs.{name}")
    except ModuleNotFoundError:
      raise AttributeError(f"module 'envs' has no attribute {name!r}") from None
  value = getattr(importlib.import_module(f"envs.{_FROM[name]}"), name)
  globals()[name] = value
  return value
