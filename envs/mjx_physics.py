"""The MJX pipeline (brax's ``mjx`` backend), the accelerator path: a ``physics.Physics``.

    physics = MjxPhysics(mj_model, n_frames=5)   # builds the MJX system of the model
    ps = physics.init(qpos, qvel)                # a brax/MJX state (qpos, qvel, ...)
    ps = physics.step(ps, ctrl)                  # n_frames pipeline steps, ctrl held

The same steps brax's ``PipelineEnv`` takes (``pipeline_init``, a ``lax.scan`` of
``pipeline.step``), without the env around them. Unstable: a NaN or Inf in qpos or qvel.
"""

from __future__ import annotations

import warnings

from envs import quiet  # noqa: F401 - before brax: mujoco.mjx's import prints nothing
import jax
import jax.numpy as jp
from brax.io import mjcf
from brax.mjx import pipeline


class MjxPhysics:
  """A MuJoCo model stepped by MJX (module doc)."""

  def __init__(self, model, n_frames: int):
    with warnings.catch_warnings():  # brax's notice that its own pipelines are unmaintained
      warnings.simplefilter("ignore", UserWarning)
      self.sys = mjcf.load_model(model)
    self.n_frames = n_frames

  def init(self, qpos: jax.Array, qvel: jax.Array):
    return pipeline.init(self.sys, qpos, qvel, None, None, False)

  def step(self, state, ctrl: jax.Array):
    f = lambda s, _: (pipeline.step(self.sys, s, ctrl, False), None)
    return jax.lax.scan(f, state, (), self.n_frames)[0]

  def unstable(self, state) -> jax.Array:
    finite = jp.all(jp.isfinite(state.qpos)) & jp.all(jp.isfinite(state.qvel))
    return 1.0 - finite.astype(jp.float32)
