"""MuJoCo 2.x's contact physics on MuJoCo 3: the settings behind ``AntConfig.contacts``.

The paper's code ran MuJoCo 2.0 (mujoco_py 2.0.2.9); this project runs MuJoCo 3. On HIRO's
ant mazes three engine changes move the ant and the blocks
(``benchmarks/physics_versions.py`` measures them, ``docs/environments.md`` has the table):

* **Contact margin.** A contact's margin is the *sum* of its two geoms' margins in MuJoCo 3
  (since 3.5), the larger of the two in 2.x. HIRO gives every geom margin 0.01, so every
  contact has margin 0.02 instead of 0.01: the ant stands 1.7 cm higher and the Push block is
  pressed onto the floor harder.
* **The blocks' inverse weight** (``body_invweight0``, which scales the contact's
  regularisation, i.e. its softness). MuJoCo 3 gives a body moved by slide joints only
  ``1 / mass``; 2.x averaged the body's inverse inertia over all three axes, a locked axis
  counting as 0. HIRO's Push block slides in x and y only (2.x: 2/3 of 1/mass) and the Fall
  block in y and z: on MuJoCo 3 their floor contacts are 1.5x softer, and the Push block
  slides 1.5x faster under the same push.
* **When the contact solve stops.** MuJoCo 3's Newton solver has early exits 2.x lacked
  (3.11: on its predicted improvement, and with no iteration when the warm start already meets
  the tolerance). At the default tolerance (1e-8) a few random-torque paths leave 2.x's by a
  part in 1e-8, which chaos then grows; at 1e-10 most of them stay on it (measured).

``apply_contacts(model, "mujoco2")`` undoes the three on a compiled model: every geom margin
(and gap) halved, so that two geoms' sum is 2.x's larger one (this needs every colliding geom
to share one margin, as HIRO's do); 2.x's inverse weight for the bodies that MuJoCo 3 treats as
slide-only; solver tolerance 1e-10. Apply it once, to a freshly compiled model, before MJX or
``envs.c_physics`` is built on it: both read these fields. It works by role (every geom, every
body), not by name, so it applies alike to our models and to the XML the paper's code writes.

What it cannot undo (the residual, measured in ``docs/environments.md``): the colliders. 2.x's
box-box collider (rewritten in MuJoCo 3) adds a spurious fifth contact when the Push block
scrapes a wall, and 2.x's capsule-box collider caps a capsule's depth in a box at its radius
(an ant's foot driven into a platform or wall). ``"mujoco3"`` leaves the model as MuJoCo 3
compiles it.
"""

from __future__ import annotations

import mujoco
import numpy as np

CONTACTS = ("mujoco3", "mujoco2")
DEFAULT = "mujoco3"  # AntConfig's and a new run's
MUJOCO2_TOLERANCE = 1e-10
_SLIDE_ONLY = 2  # mjModel.body_simple of a body moved by slide joints only (MuJoCo 3)


def apply_contacts(model: mujoco.MjModel, name: str) -> None:
  """Give a compiled ``model`` the contact settings ``name`` (``CONTACTS``), in place."""
  if name not in CONTACTS:
    raise ValueError(f"contacts must be one of {', '.join(CONTACTS)}, got {name!r}")
  if name == "mujoco2":
    halve_margins(model)
    legacy_invweight(model)
    model.opt.tolerance = min(model.opt.tolerance, MUJOCO2_TOLERANCE)


def halve_margins(model: mujoco.MjModel) -> None:
  """Halve every geom's margin and gap (and the bodies' collision bounds, which MuJoCo 3 adds
  the same way), so that a contact's sum of two equal margins is what 2.x's larger one was.

  Raises ValueError if colliding geoms differ in margin or gap: then no per-geom value gives
  2.x's max for every pair."""
  colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
  for field in ("geom_margin", "geom_gap"):
    values = np.unique(getattr(model, field)[colliding])
    if values.size > 1:
      raise ValueError(f"{field} differs between colliding geoms ({values.tolist()}): "
                       "halving them would not give MuJoCo 2's larger-of-two for every pair")
  model.geom_margin[:] *= 0.5
  model.geom_gap[:] *= 0.5
  if hasattr(model, "body_margin"):
    model.body_margin[:] *= 0.5


def legacy_invweight(model: mujoco.MjModel) -> None:
  """MuJoCo 2.x's ``body_invweight0`` for the bodies MuJoCo 3 gives ``1 / mass`` (moved by
  slide joints only): the mean of the translational and of the rotational diagonal of
  J M^-1 J' at ``qpos0``, a locked axis counting as 0 (2.x ``mj_setConst``)."""
  bodies = [b for b in range(1, model.nbody) if model.body_simple[b] == _SLIDE_ONLY]
  if not bodies:
    return
  data = mujoco.MjData(model)
  mujoco.mj_forward(model, data)
  jac, minv_jac = np.zeros((6, model.nv)), np.zeros((6, model.nv))
  for b in bodies:
    mujoco.mj_jacBodyCom(model, data, jac[:3], jac[3:], b)
    mujoco.mj_solveM(model, data, minv_jac, jac)
    inv = jac @ minv_jac.T
    model.body_invweight0[b] = (np.trace(inv[:3, :3]) / 3, np.trace(inv[3:, 3:]) / 3)
