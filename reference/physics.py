"""Engine settings applied to each MuJoCo model the reference loads (``--physics NAME``).

A setting is a function of the freshly loaded ``mujoco.MjModel`` that changes it in place
(its options, geom margins, ...), applied by the mujoco_py stand-in before the model's data
is made. Only "as-is" (the model as its XML says) is defined here; others are registered
with ``register``.
"""

SETTINGS = {"as-is": None}


def register(name, fn):
  """Add a named setting: ``fn(model)`` changes a loaded ``mujoco.MjModel`` in place."""
  SETTINGS[name] = fn


def hook(name):
  """The function for a setting's name (None for "as-is")."""
  if name not in SETTINGS:
    raise ValueError(f"unknown physics {name!r}; known: {', '.join(sorted(SETTINGS))}")
  return SETTINGS[name]
