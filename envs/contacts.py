"""MuJoCo 2's physics on MuJoCo 3: the settings behind ``AntConfig.contacts``.

The paper's code ran MuJoCo 2.0 (mujoco_py 2.0.2.9); this project runs MuJoCo 3. On HIRO's
ant mazes three engine changes between 2.3 and 3 move the ant and the blocks
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

One more change, between 2.0 and 2.1.1, moves the ant as much: MuJoCo 2.0 computed a capsule's
mass and inertia as those of a cylinder of its middle section extended by half its radius at
both ends (MuJoCo's changelog, 2.1.1; the masses match mujoco_py 2.0's Reacher-v2 in gym issue
2039). HIRO's ant, legs of capsules, weighs 0.879 there instead of 0.911 and stands 1-2 mm
lower. No pip-installable MuJoCo has it, so no fixture checks it.

``apply_contacts(model, "mujoco2")`` undoes the three on a compiled model: every geom margin
(and gap) halved, so that two geoms' sum is 2.x's larger one (this needs every colliding geom
to share one margin, as HIRO's do); 2.x's inverse weight for the bodies that MuJoCo 3 treats as
slide-only; solver tolerance 1e-10. Apply it once, to a freshly compiled model, before MJX or
``envs.c_physics`` is built on it: both read these fields. It works by role (every geom, every
body), not by name, so it applies alike to our models and to the XML the paper's code writes.
``"mujoco200"`` also gives the capsule bodies 2.0's masses and inertias (``capsule_inertia``).

What it cannot undo (the residual, measured in ``docs/environments.md``): the colliders. 2.x's
box-box collider (rewritten in MuJoCo 3) adds a spurious fifth contact when the Push block
scrapes a wall, and 2.x's capsule-box collider caps a capsule's depth in a box at its radius
(an ant's foot driven into a platform or wall). ``"mujoco3"`` leaves the model as MuJoCo 3
compiles it.
"""

from __future__ import annotations

import mujoco
import numpy as np

CONTACTS = ("mujoco3", "mujoco2", "mujoco200")
DEFAULT = "mujoco3"  # AntConfig's (envs.make): MuJoCo 3 as it compiles the model
# A new run's (``--contacts``): the closest this engine comes to the paper's MuJoCo 2.0, with
# the one part no fixture can check (2.0's capsule inertia); ``mujoco2`` is the checked one
RUN_DEFAULT = "mujoco200"
MUJOCO2_TOLERANCE = 1e-10
_SLIDE_ONLY = 2  # mjModel.body_simple of a body moved by slide joints only (MuJoCo 3)


def apply_contacts(model: mujoco.MjModel, name: str) -> None:
  """Give a compiled ``model`` the contact settings ``name`` (``CONTACTS``), in place."""
  if name not in CONTACTS:
    raise ValueError(f"contacts must be one of {', '.join(CONTACTS)}, got {name!r}")
  if name == "mujoco200":  # first: mj_setConst recomputes the inverse weights
    capsule_inertia(model, legacy=True)
  if name in ("mujoco2", "mujoco200"):
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


def _geom_inertia(model, g: int, density: float, legacy: bool):
  """(mass, volume, position, 3x3 inertia about the geom's centre in the body frame) of a
  sphere or capsule; ``legacy``: a capsule as MuJoCo 2.0's cylinder of length L + r."""
  r, half = model.geom_size[g, 0], model.geom_size[g, 1]
  if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
    volume = 4 / 3 * np.pi * r**3
    mass = density * volume
    axes = np.full(3, 0.4 * mass * r * r)
  elif legacy:  # 2.0: a cylinder of the middle section extended by r / 2 at both ends
    length = 2 * half + r
    volume = np.pi * r * r * length
    mass = density * volume
    axes = np.array([mass * (3 * r * r + length**2) / 12] * 2 + [mass * r * r / 2])
  else:  # exact: a cylinder and two hemispheres (parallel axis theorem)
    cyl, hemi = density * np.pi * r * r * 2 * half, density * 2 / 3 * np.pi * r**3
    mass, volume = cyl + 2 * hemi, np.pi * r * r * 2 * half + 4 / 3 * np.pi * r**3
    offset = half + 3 / 8 * r  # a hemisphere's centre of mass from the capsule's centre
    hemi_perp = hemi * (0.4 * r * r - (3 / 8 * r) ** 2 + offset**2)
    perp = cyl * (3 * r * r + 4 * half * half) / 12 + 2 * hemi_perp
    axes = np.array([perp, perp, cyl * r * r / 2 + 2 * hemi * 0.4 * r * r])
  rot = np.zeros(9)
  mujoco.mju_quat2Mat(rot, model.geom_quat[g])
  rot = rot.reshape(3, 3)
  return mass, volume, model.geom_pos[g].copy(), rot @ np.diag(axes) @ rot.T


def _body_inertial(model, b: int, legacy: bool):
  """(mass, centre of mass, principal-axes quaternion, principal inertia) of body ``b`` from
  its geoms at the one density that gives its compiled mass."""
  geoms = range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b])
  exact_volume = sum(_geom_inertia(model, g, 1.0, False)[1] for g in geoms)
  parts = [_geom_inertia(model, g, model.body_mass[b] / exact_volume, legacy) for g in geoms]
  mass = sum(p[0] for p in parts)
  com = sum(p[0] * p[2] for p in parts) / mass
  tensor = sum(i + m * ((p - com) @ (p - com) * np.eye(3) - np.outer(p - com, p - com))
               for m, _, p, i in parts)
  principal, axes = np.linalg.eigh(tensor)
  if np.linalg.det(axes) < 0:
    axes[:, 0] *= -1
  quat = np.zeros(4)
  mujoco.mju_mat2Quat(quat, axes.flatten())
  return mass, com, quat, principal


def capsule_inertia(model: mujoco.MjModel, legacy: bool = True) -> None:
  """Masses and inertias of the bodies with capsules, recomputed from their geoms:
  ``legacy``, MuJoCo 2.0's (fixed in 2.1.1), each capsule a cylinder of its middle section
  extended by half its radius at both ends (HIRO's ant: 0.879 instead of 0.911); else the
  exact ones MuJoCo 3 compiles. For bodies whose inertia comes from their spheres and
  capsules at one density (HIRO's ``inertiafromgeom``); other bodies are left alone."""
  sphere, capsule = int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE)
  for b in range(1, model.nbody):
    types = {int(t) for t in model.geom_type[model.body_geomadr[b]:
                                             model.body_geomadr[b] + model.body_geomnum[b]]}
    if capsule not in types or not types <= {sphere, capsule}:
      continue
    model.body_mass[b], model.body_ipos[b], model.body_iquat[b], model.body_inertia[b] = (
        _body_inertial(model, b, legacy))
  mujoco.mj_setConst(model, mujoco.MjData(model))
