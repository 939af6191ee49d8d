"""What every maze task shares: target, success, reward, the episode clock and the state type.

Task reward is HIRO's ``-||xyz_torso - target||`` (3-D); success is that distance <= the task's
success radius. The env never terminates by itself: ``done`` is raised only by ``truncation``
when the step counter reaches ``episode_length``; the caller resets. ``MazeEnv`` is the
contract the agent relies on; both robots implement it.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

from envs import quiet  # noqa: F401 - before brax: mujoco.mjx's import prints nothing
import jax
import jax.numpy as jp
import mujoco
from brax.envs import base as brax_base
from flax import struct

from envs import maze

TIME_SCALE = 0.001  # last observation entry: t * 0.001 (HIRO)


@struct.dataclass
class MazeState(brax_base.State):
  """brax's env state plus the episode clock and the task's outcome as typed fields.

  ``metrics`` holds ``reward_task`` (-distance), ``distance`` and ``success`` (0/1) too, as
  brax's envs do. (The defaults are brax's convention for fields after defaulted ones.)
  """

  steps: jax.Array = None  # steps taken in this episode (int32)
  truncation: jax.Array = None  # 1.0 at the last step of an episode
  success: jax.Array = None  # 1.0 within the task's success radius of the target
  distance: jax.Array = None  # ||xyz - target||


@runtime_checkable
class MazeEnv(Protocol):
  """The env contract of the agent: ``obs[:3]`` is the robot's xyz, the target is an xyz
  point, actions lie in ``[-action_limit, action_limit]``, and every state carries
  ``success`` and ``distance``; the env never ends an episode by itself."""

  target: jax.Array  # (3,) xyz
  success_radius: float

  @property
  def observation_size(self) -> int: ...

  @property
  def action_size(self) -> int: ...

  @property
  def action_limit(self) -> float: ...

  @property
  def episode_length(self) -> int: ...

  def reset(self, rng: jax.Array) -> MazeState: ...

  def step(self, state: MazeState, action: jax.Array) -> MazeState: ...

  def block_positions(self, state: MazeState) -> jax.Array: ...

  def unstable(self, state: MazeState) -> jax.Array: ...


@dataclasses.dataclass(frozen=True)
class EnvConfig:
  """Options every maze env takes (``envs.make(name, **overrides)``)."""

  episode_length: int = 1000  # the paper's code; HIRO evaluated 500-step episodes
  reset_noise_scale: float = 0.1

  def __post_init__(self):
    if self.episode_length <= 0:
      raise ValueError(f"episode_length must be positive, got {self.episode_length}")
    if self.reset_noise_scale < 0:
      raise ValueError(f"reset_noise_scale must be >= 0, got {self.reset_noise_scale}")


class MazeTask:
  """Mixin: the task logic shared by the ant and the point robot.

  Subclasses set ``layout``, ``target``, ``success_radius``, ``config`` and ``mj_model``.
  """

  layout: maze.MazeLayout
  target: jax.Array
  success_radius: float
  config: EnvConfig
  mj_model: mujoco.MjModel

  @property
  def episode_length(self) -> int:
    return self.config.episode_length

  def unstable(self, state: MazeState) -> jax.Array:
    """1.0 if the step that made ``state`` left the physics unstable (the run stops on it)."""
    return jp.zeros((), jp.float32)

  def task_metrics(self, xyz: jax.Array) -> dict[str, jax.Array]:
    distance = jp.linalg.norm(xyz - self.target)
    return {
        "reward_task": -distance,
        "distance": distance,
        "success": (distance <= self.success_radius).astype(jp.float32),
    }

  def clock(self, steps: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(time observation entry, truncation flag) for a step count."""
    truncation = (steps >= self.config.episode_length).astype(jp.float32)
    return jp.array([steps * TIME_SCALE], jp.float32), truncation

  def make_state(self, pipeline_state, obs_body: jax.Array, xyz: jax.Array,
                 steps: jax.Array) -> MazeState:
    time_obs, truncation = self.clock(steps)
    metrics = self.task_metrics(xyz)
    return MazeState(
        pipeline_state=pipeline_state,
        obs=jp.concatenate([obs_body, time_obs]),
        reward=metrics["reward_task"],
        done=truncation,
        metrics=metrics,
        steps=steps,
        truncation=truncation,
        success=metrics["success"],
        distance=metrics["distance"],
    )
