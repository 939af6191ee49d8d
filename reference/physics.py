"""Engine settings applied to each MuJoCo model the reference loads (``--physics NAME``).

A setting is a function of the freshly loaded ``mujoco.MjModel`` that changes it in place
(its options, geom margins, ...), applied by the mujoco_py stand-in before the model's data
is made. "as-is" (the model as its XML says, which is MuJoCo 3's ``mujoco3``) and the
project's contact settings (``envs/contacts.py``: ``mujoco2``, ``mujoco200``), the same
function that our env applies, so that both sides of a comparison step one engine alike.
"""

import importlib.util
import pathlib

CONTACTS_FILE = pathlib.Path(__file__).resolve().parents[1] / "envs" / "contacts.py"
SETTINGS = {"as-is": None}


def register(name, fn):
  """Add a named setting: ``fn(model)`` changes a loaded ``mujoco.MjModel`` in place."""
  SETTINGS[name] = fn


def _contacts():
  """``envs/contacts.py`` loaded from its file: the reference venv has mujoco and numpy but
  not the project's jax, which ``import envs`` would pull in."""
  spec = importlib.util.spec_from_file_location("_project_contacts", CONTACTS_FILE)
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  return module


def names():
  """Every setting's name: "as-is" and the project's contact settings."""
  return sorted(SETTINGS) + [n for n in _contacts().CONTACTS if n not in SETTINGS]


def hook(name):
  """The function for a setting's name (None for "as-is" and "mujoco3")."""
  if name in SETTINGS:
    return SETTINGS[name]
  contacts = _contacts()
  if name not in contacts.CONTACTS:
    raise ValueError(f"unknown physics {name!r}; known: {', '.join(names())}")
  if name == "mujoco3":
    return None
  return lambda model: contacts.apply_contacts(model, name)
