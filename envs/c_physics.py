"""MuJoCo's C engine from inside a jitted program: many simulations stepped at once on the host.

The MJX pipeline is MuJoCo rewritten in JAX, made for accelerators; on an x86 CPU it runs the
ant about 10-25x slower than MuJoCo's C engine on the same model. ``CPhysics`` keeps the env a
pure function of its state for JAX (``jit``, ``vmap``, ``lax.scan``, ``shard_map``, ``cond``)
and hands only the physics step to the host through ``jax.pure_callback``:

    physics = CPhysics(mj_model, n_frames=5)
    ps = physics.init(qpos, qvel)      # a CState, vmappable
    ps = physics.step(ps, ctrl)        # n_frames mj_step of every simulation of the call

Under ``vmap`` (``vmap_method="broadcast_all"``) one callback receives every simulation of the
program (seeds x envs, or seeds x evaluation episodes) and steps them together with
``mujoco.batch.Batch`` on a thread pool: results are bit-identical to one ``MjData`` per
simulation at any thread count. A device's callback uses ``cores // local devices`` threads, so
that with ``--cpu-devices 2`` two devices stepping at once use the two cores.

The state that crosses. ``CState.bits`` is the simulation's row of MuJoCo's integration state
(``mj_getState``) up to and including the solver's warm start: time, qpos, qvel, act, history,
qacc_warmstart, every float64 stored as its bit pattern (two uint32 each: JAX runs in float32).
This is everything ``mj_step`` changes; the rest of the integration state (applied forces,
equality flags, mocap, user data) stays at the model's defaults and ``ctrl`` is the step's
action. So a checkpoint of a ``CState`` restores the physics bit for bit. ``qpos`` / ``qvel``
are float32 copies for observations and rendering; ``unstable`` is 1.0 where MuJoCo found the
simulation unstable during the step (a bad qpos, qvel or qacc warning, after which it resets
that simulation, or an error in the engine): the trainer stops on it (``nonmono_jax.host.run``).
"""

from __future__ import annotations

import contextlib
import math
import os
import threading

import jax
import jax.numpy as jp
import mujoco
import numpy as np
from flax import struct
from mujoco import batch as mj_batch

_S = mujoco.mjtState
# A prefix of the integration row (its components are laid out in bit order).
CARRIED = (_S.mjSTATE_TIME | _S.mjSTATE_QPOS | _S.mjSTATE_QVEL | _S.mjSTATE_ACT
           | _S.mjSTATE_HISTORY | _S.mjSTATE_WARMSTART)
_W = mujoco.mjtWarning
UNSTABLE_WARNINGS = [int(w) for w in (_W.mjWARN_BADQPOS, _W.mjWARN_BADQVEL, _W.mjWARN_BADQACC)]


@struct.dataclass
class CState:
  """One simulation's physics state for the C engine (module doc)."""

  bits: jax.Array  # (2 * carried,) uint32: the float64 row of mj_getState(CARRIED)
  qpos: jax.Array  # (nq,) float32
  qvel: jax.Array  # (nv,) float32
  unstable: jax.Array  # () float32: 1.0 if MuJoCo flagged the last step


def host_threads() -> int:
  """Threads of one device's batch: the usable cores shared by this process's devices."""
  try:
    cores = len(os.sched_getaffinity(0))
  except AttributeError:  # not on Linux
    cores = os.cpu_count() or 1
  return max(1, cores // max(1, jax.local_device_count()))


class _BatchPool:
  """``mujoco.batch.Batch``es of one model by size. A batch must not be used by two threads
  at once, and devices call back concurrently: each call takes a free batch of its size (or
  makes one) and gives it back."""

  def __init__(self, model: mujoco.MjModel):
    self._model = model
    self._free: dict[int, list] = {}
    self._lock = threading.Lock()

  @contextlib.contextmanager
  def take(self, nsim: int):
    with self._lock:
      free = self._free.setdefault(nsim, [])
      batch = free.pop() if free else None
    if batch is None:
      batch = mj_batch.Batch(self._model, nsim, host_threads())
    try:
      yield batch
    finally:
      with self._lock:
        self._free[nsim].append(batch)


class CPhysics:
  """``init``, ``step`` and ``unstable`` of a model's simulations in MuJoCo C, callable from
  jitted code: a ``physics.Physics``."""

  def __init__(self, model: mujoco.MjModel, n_frames: int):
    if model.nplugin:
      raise ValueError("CPhysics carries no plugin state: the model must have no plugins")
    self.model, self.n_frames = model, n_frames
    self.width = mujoco.mj_stateSize(model, int(CARRIED))  # float64 values carried
    self._nq, self._nv = model.nq, model.nv
    # where each quaternion of the qpos starts: a free joint's after its position, a ball's
    kinds = {int(mujoco.mjtJoint.mjJNT_FREE): 3, int(mujoco.mjtJoint.mjJNT_BALL): 0}
    self._quaternions = [int(adr) + kinds[int(kind)]
                         for kind, adr in zip(model.jnt_type, model.jnt_qposadr)
                         if int(kind) in kinds]
    self._pool = _BatchPool(model)

  def _shapes(self, lead=()) -> CState:
    f32 = lambda *s: jax.ShapeDtypeStruct(lead + s, jp.float32)
    return CState(bits=jax.ShapeDtypeStruct(lead + (2 * self.width,), jp.uint32),
                  qpos=f32(self._nq), qvel=f32(self._nv), unstable=f32())

  # --- the jitted side ----------------------------------------------------------------------

  def init(self, qpos: jax.Array, qvel: jax.Array) -> CState:
    """The state at ``qpos``, ``qvel`` (float32), time 0, no warm start; each quaternion of
    ``qpos`` (free and ball joints) normalised, as MJX's forward pass leaves it."""
    for i in self._quaternions:
      qpos = qpos.at[i:i + 4].set(qpos[i:i + 4] / jp.linalg.norm(qpos[i:i + 4]))
    return jax.pure_callback(self._host_init, self._shapes(), qpos.astype(jp.float32),
                             qvel.astype(jp.float32), vmap_method="broadcast_all")

  def unstable(self, state: CState) -> jax.Array:
    """1.0 where MuJoCo flagged the step that made ``state`` (module doc)."""
    return state.unstable

  def step(self, state: CState, ctrl: jax.Array) -> CState:
    """``n_frames`` calls of ``mj_step`` with ``ctrl`` held."""
    return jax.pure_callback(self._host_step, self._shapes(), state.bits,
                             ctrl.astype(jp.float32), vmap_method="broadcast_all")

  # --- the host side ------------------------------------------------------------------------

  def _out(self, rows: np.ndarray, unstable: np.ndarray, lead: tuple) -> CState:
    nq, nv = self._nq, self._nv
    return CState(bits=np.ascontiguousarray(rows).view(np.uint32).reshape(*lead, -1),
                  qpos=rows[:, 1:1 + nq].astype(np.float32).reshape(*lead, nq),
                  qvel=rows[:, 1 + nq:1 + nq + nv].astype(np.float32).reshape(*lead, nv),
                  unstable=unstable.astype(np.float32).reshape(lead))

  def _host_init(self, qpos: np.ndarray, qvel: np.ndarray) -> CState:
    lead = qpos.shape[:-1]
    n = math.prod(lead)
    rows = np.zeros((n, self.width))
    rows[:, 1:1 + self._nq] = qpos.reshape(n, self._nq)
    rows[:, 1 + self._nq:1 + self._nq + self._nv] = qvel.reshape(n, self._nv)
    return self._out(rows, np.zeros(n), lead)

  def _host_step(self, bits: np.ndarray, ctrl: np.ndarray) -> CState:
    lead = ctrl.shape[:-1]
    n = math.prod(lead)
    if n == 0:
      return self._out(np.zeros((0, self.width)), np.zeros(0), lead)
    rows = np.ascontiguousarray(bits).reshape(n, 2 * self.width).view(np.float64)
    with self._pool.take(n) as batch:
      batch.state[:, :self.width] = rows
      batch.ctrl[:] = ctrl.reshape(n, -1)
      warned = batch.warning[:, UNSTABLE_WARNINGS, 1].sum(-1)
      try:
        batch.step(nstep=self.n_frames)
        failed = np.zeros(n, bool)
      except mj_batch.SimulationError as e:  # those simulations kept their state
        failed = np.isin(np.arange(n), e.ids)
      unstable = (batch.warning[:, UNSTABLE_WARNINGS, 1].sum(-1) > warned) | failed
      out = batch.state[:, :self.width].copy()
    return self._out(out, unstable, lead)
