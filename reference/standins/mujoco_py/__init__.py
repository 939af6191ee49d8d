"""A stand-in for ``mujoco_py`` 2.0.2.9 over the official ``mujoco`` bindings.

It covers what gym 0.15.7's ``mujoco_env.MujocoEnv`` and the paper's maze env touch, with
mujoco_py's semantics (``mujoco_py/mjsim.pyx``):

* ``MjSim.step()`` calls ``mj_step`` ``nsubsteps`` times (1 unless given); gym's
  ``do_simulation`` sets ``data.ctrl[:]`` and calls ``step()`` frame-skip times;
* ``MjSim.reset()`` is ``mj_resetData``; ``forward()`` is ``mj_forward``;
* ``get_state()`` / ``set_state()`` copy time, qpos, qvel, act (None when ``na == 0``) and the
  user-defined-dynamics state, and nothing else (not ctrl, not the solver's warm start);
* a MuJoCo warning raised inside a call (e.g. "Nan, Inf or huge value in QACC") becomes a
  ``MujocoException`` after the call, as mujoco_py's default warning callback does
  (``set_warning_mode("count")`` only counts them instead);
* rendering (``MjViewer``, ``MjRenderContextOffscreen``) raises.

``set_model_hook(fn)`` installs a function applied to every ``mujoco.MjModel`` right after it
is loaded (before its ``MjData`` is made), the place where engine settings can be changed.
"""

import collections
import copy

import mujoco
import numpy as np

__version__ = "2.0.2.9"
_VERSION = "2.0.2.9"

_model_hook = None
_warning_mode = "raise"
warning_counts = collections.Counter()  # warning name -> how many were seen


class MujocoException(Exception):
  """What mujoco_py raises when MuJoCo warns inside a call."""


def get_version():
  """The mujoco_py version this stands in for (the maze env compares it with '1.50')."""
  return _VERSION


def set_model_hook(fn):
  """Apply ``fn(model: mujoco.MjModel)`` to every model loaded from now on (None: none)."""
  global _model_hook
  _model_hook = fn


def set_warning_mode(mode):
  """'raise' (mujoco_py's default: a MuJoCo warning raises MujocoException) or 'count'."""
  global _warning_mode
  if mode not in ("raise", "count"):
    raise ValueError(f"warning mode must be 'raise' or 'count', got {mode!r}")
  _warning_mode = mode


class PyMjModel:
  """The loaded ``mujoco.MjModel`` with mujoco_py's name-to-id helpers; other attributes are
  the official model's (``opt.timestep``, ``actuator_ctrlrange``, ``nq``, ``nv``, ...)."""

  def __init__(self, model):
    self._model = model
    self._ids = {}

  def __getattr__(self, name):
    return getattr(self._model, name)

  @property
  def ptr(self):
    """The official ``mujoco.MjModel``."""
    return self._model

  def _id(self, kind, name):
    key = (kind, name)
    if key not in self._ids:
      index = mujoco.mj_name2id(self._model, kind, name)
      if index < 0:
        raise ValueError(f'No "{name}" {kind.name[6:].lower()} exists.')
      self._ids[key] = index
    return self._ids[key]

  def body_name2id(self, name):
    return self._id(mujoco.mjtObj.mjOBJ_BODY, name)

  def geom_name2id(self, name):
    return self._id(mujoco.mjtObj.mjOBJ_GEOM, name)

  def joint_name2id(self, name):
    return self._id(mujoco.mjtObj.mjOBJ_JOINT, name)

  def site_name2id(self, name):
    return self._id(mujoco.mjtObj.mjOBJ_SITE, name)

  def camera_name2id(self, name):
    return self._id(mujoco.mjtObj.mjOBJ_CAMERA, name)

  @property
  def _camera_name2id(self):
    names = (mujoco.mj_id2name(self._model, mujoco.mjtObj.mjOBJ_CAMERA, i)
             for i in range(self._model.ncam))
    return {name: i for i, name in enumerate(names)}

  @property
  def body_names(self):
    return tuple(mujoco.mj_id2name(self._model, mujoco.mjtObj.mjOBJ_BODY, i)
                 for i in range(self._model.nbody))


class PyMjData:
  """The official ``mujoco.MjData`` (``qpos``, ``qvel``, ``ctrl``, ``xpos``, ``time``, ... as
  writable views) with mujoco_py's ``get_body_*`` accessors."""

  def __init__(self, data, model):
    object.__setattr__(self, "_data", data)
    object.__setattr__(self, "_model", model)

  def __getattr__(self, name):
    return getattr(self._data, name)

  def __setattr__(self, name, value):
    setattr(self._data, name, value)

  @property
  def ptr(self):
    """The official ``mujoco.MjData``."""
    return self._data

  def get_body_xpos(self, name):
    return self._data.xpos[self._model.body_name2id(name)]

  def get_body_xquat(self, name):
    return self._data.xquat[self._model.body_name2id(name)]

  def get_body_xmat(self, name):
    return self._data.xmat[self._model.body_name2id(name)].reshape(3, 3)

  def get_body_xvelp(self, name):
    vel = np.zeros(6)
    mujoco.mj_objectVelocity(self._model.ptr, self._data, mujoco.mjtObj.mjOBJ_BODY,
                             self._model.body_name2id(name), vel, 0)
    return vel[3:]

  def get_geom_xpos(self, name):
    return self._data.geom_xpos[self._model.geom_name2id(name)]

  def get_site_xpos(self, name):
    return self._data.site_xpos[self._model.site_name2id(name)]


MjSimState = collections.namedtuple("MjSimState", "time qpos qvel act udd_state")


def load_model_from_path(path):
  """Load an XML (or MJB) model, apply the model hook, wrap it."""
  if path.endswith(".mjb"):
    model = mujoco.MjModel.from_binary_path(path)
  elif path.endswith(".xml"):
    model = mujoco.MjModel.from_xml_path(path)
  else:
    raise RuntimeError(f"Unrecognized extension for {path}. Expected .xml or .mjb")
  if _model_hook is not None:
    _model_hook(model)
  return PyMjModel(model)


def load_model_from_xml(xml):
  """Load a model from an XML string, apply the model hook, wrap it."""
  model = mujoco.MjModel.from_xml_string(xml)
  if _model_hook is not None:
    _model_hook(model)
  return PyMjModel(model)


def raise_warnings(data):
  """After a MuJoCo call: count the warnings it raised and, in 'raise' mode, raise
  MujocoException. The counters are zeroed once read (an unstable state resets the data and
  sets its counter to 1, so a second such step would not show as an increase); they are
  statistics, not part of the dynamics."""
  number = data.warning.number
  if number.any():
    names = [mujoco.mjtWarning(i).name for i in np.flatnonzero(number)]
    warning_counts.update(names)
    number[:] = 0
    if _warning_mode == "raise":
      raise MujocoException(f"Got MuJoCo Warning: {', '.join(names)}")


class MjSim:
  """A running simulation: ``model``, ``data`` and mujoco_py's step, reset, forward and
  state copies."""

  def __init__(self, model, data=None, nsubsteps=1, udd_callback=None, **_):
    self.model = model
    self.data = data if data is not None else PyMjData(mujoco.MjData(model.ptr), model)
    self.nsubsteps = nsubsteps
    self._udd_callback = udd_callback
    self.udd_state = None
    self.extras = {}
    self.render_contexts = []
    self._step_udd()

  def _step_udd(self):
    if self._udd_callback is None:
      self.udd_state = {}
    else:
      self.udd_state = self._udd_callback(self)

  def _checked(self, fn):
    fn(self.model.ptr, self.data.ptr)
    raise_warnings(self.data.ptr)

  def step(self, with_udd=True):
    """``mj_step`` ``nsubsteps`` times (mujoco_py's ``MjSim.step``)."""
    if with_udd:
      self._step_udd()
    for _ in range(self.nsubsteps):
      self._checked(mujoco.mj_step)

  def forward(self):
    """``mj_forward``."""
    self._checked(mujoco.mj_forward)

  def reset(self):
    """``mj_resetData``, then a fresh user-defined-dynamics state."""
    mujoco.mj_resetData(self.model.ptr, self.data.ptr)
    self.udd_state = None
    self._step_udd()

  def get_state(self):
    """A copy of time, qpos, qvel, act (None without activations) and udd_state."""
    act = None if self.model.na == 0 else np.copy(self.data.act)
    return MjSimState(self.data.time, np.copy(self.data.qpos), np.copy(self.data.qvel), act,
                      copy.deepcopy(self.udd_state))

  def set_state(self, value):
    """Set time, qpos, qvel, act and udd_state from an ``MjSimState`` (nothing else)."""
    self.data.time = value.time
    self.data.qpos[:] = np.copy(value.qpos)
    self.data.qvel[:] = np.copy(value.qvel)
    if self.model.na != 0:
      self.data.act[:] = np.copy(value.act)
    self.udd_state = copy.deepcopy(value.udd_state)

  def render(self, *args, **kwargs):
    raise NotImplementedError("the mujoco_py stand-in does not render")


class MjViewer:
  """Rendering is not part of the stand-in."""

  def __init__(self, *args, **kwargs):
    raise NotImplementedError("the mujoco_py stand-in has no viewer")


MjRenderContextOffscreen = MjViewer
MjRenderContextWindow = MjViewer


class ignore_mujoco_warnings:
  """mujoco_py's context manager: count MuJoCo warnings instead of raising inside it."""

  def __enter__(self):
    global _warning_mode
    self._previous, _warning_mode = _warning_mode, "count"
    return self

  def __exit__(self, *exc):
    global _warning_mode
    _warning_mode = self._previous
