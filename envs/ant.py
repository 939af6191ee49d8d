"""The rllab/HIRO ant (HIRO ``environments/assets/ant.xml``) and its maze models.

Torso sphere r 0.25 at z 0.75 (raised by the platform height in an elevated maze), four legs of
capsules r 0.08, 8 hinge motors with ctrlrange +-30 and gear 1, joint damping 1 and armature 1,
geom friction (1, 0.5, 0.5), density 5, margin 0.01; RK4 at 0.02 s.

Contacts. HIRO lets every ant geom collide with every wall, platform, block and the floor
(contype 1, conaffinity 0 on the ant; 1/1 on the world). ``optimised=True`` keeps the same
solid world but

* merges wall and platform cells into few boxes and makes walls nobody can reach render-only
  (``envs.maze``);
* lets only the torso and the eight leg capsules collide (the four hip connectors sit inside
  the torso's reach, so whatever they could touch the torso or the thighs touch first);
* uses 8 Newton iterations and 8 line-search steps instead of 100 / 50 (the same trajectories
  in MuJoCo C; 4 or fewer iterations visibly change them), and caps what MJX computes: the
  narrow phase runs on the 16 nearest pairs of each geom-type pair (``max_geom_pairs``; the
  ant's 8 capsules standing on one box make 8, so fewer would drop feet) and at most 32
  contacts enter the solver (``max_contact_points``; MJX allocates constraint rows for every
  candidate contact, so this bounds the solver's size).

Kept as HIRO has them, because changing them changes the motion: RK4 (Euler at 0.02 s moves
the ant visibly differently), the block's contact with the floor (HIRO's blocks have no z
freedom, so the floor acts as a brake that keeps the Push block from drifting), solimp.

``tests/test_ant_physics.py`` runs both builds under the same controls with MuJoCo C and checks
that the ant's motion stays close.
"""

from __future__ import annotations

import dataclasses

import mujoco

from envs import maze

ACTION_SIZE = 8
CTRL_LIMIT = 30.0
TORSO_Z = 0.75


@dataclasses.dataclass(frozen=True)
class SolverSettings:
  """MuJoCo solver options (``<option>``) and MJX contact caps (``<numeric>``)."""

  iterations: int = 100
  ls_iterations: int = 50
  max_contact_points: int = -1  # MJX only: keep at most this many contacts (-1: all)
  max_geom_pairs: int = -1  # MJX only: narrow phase on this many nearest pairs per kind


HIRO_SOLVER = SolverSettings()
# Measured in tests/test_ant_physics.py against HIRO_SOLVER on the unoptimised build.
FAST_SOLVER = SolverSettings(iterations=8, ls_iterations=8, max_contact_points=32,
                             max_geom_pairs=16)


def _leg(name: str, aux: str, leg: str, ankle: str, sx: float, sy: float, hip: str,
         ankle_j: str, ankle_axis: str, ankle_range: str, aux_attr: str) -> str:
  return f"""
      <body name="{name}" pos="0 0 0">
        <geom fromto="0 0 0 {0.2*sx:g} {0.2*sy:g} 0" name="{aux}" size="0.08" type="capsule"{aux_attr}/>
        <body name="aux_{hip[-1]}" pos="{0.2*sx:g} {0.2*sy:g} 0">
          <joint axis="0 0 1" name="{hip}" pos="0 0 0" range="-30 30" type="hinge"/>
          <geom fromto="0 0 0 {0.2*sx:g} {0.2*sy:g} 0" name="{leg}" size="0.08" type="capsule"/>
          <body pos="{0.2*sx:g} {0.2*sy:g} 0">
            <joint axis="{ankle_axis}" name="{ankle_j}" pos="0 0 0" range="{ankle_range}" type="hinge"/>
            <geom fromto="0 0 0 {0.4*sx:g} {0.4*sy:g} 0" name="{ankle}" size="0.08" type="capsule"/>
          </body>
        </body>
      </body>"""


def _contact_bits(optimised: bool):
  """(ant contype, floor, static and block (contype, conaffinity), the aux geoms' attribute):
  the optimised model's collision filter, or HIRO's all-ones."""
  if optimised:
    return (maze.BIT_STATIC | maze.BIT_FLOOR, (0, maze.BIT_FLOOR), (0, maze.BIT_STATIC),
            (maze.BIT_STATIC | maze.BIT_FLOOR, maze.BIT_STATIC), ' contype="0" conaffinity="0"')
  return 1, (1, 1), (1, 1), (1, 1), ""


def _numerics(solver: SolverSettings) -> str:
  numerics = ""
  if solver.max_contact_points > -1:
    numerics += f'<numeric name="max_contact_points" data="{solver.max_contact_points}"/>'
  if solver.max_geom_pairs > -1:
    numerics += f'<numeric name="max_geom_pairs" data="{solver.max_geom_pairs}"/>'
  return numerics


def ant_maze_xml(layout: maze.MazeLayout, optimised: bool = True,
                 solver: SolverSettings | None = None) -> str:
  """The MJCF of HIRO's ant in a maze (the ant alone on a flat floor for an all-free grid)."""
  solver = solver or (FAST_SOLVER if optimised else HIRO_SOLVER)
  has_blocks = bool(layout.blocks())
  # HIRO maze_env.py: with movable blocks, stiffer default contacts.
  solimp = ' solimp=".995 .995 .01"' if has_blocks else ""
  ant_bits, floor_bits, static_bits, block_bits, aux_attr = _contact_bits(optimised)
  z0 = TORSO_Z + layout.floor_z
  legs = "".join([
      _leg("front_left_leg", "aux_1_geom", "left_leg_geom", "left_ankle_geom", 1, 1,
           "hip_1", "ankle_1", "-1 1 0", "30 70", aux_attr),
      _leg("front_right_leg", "aux_2_geom", "right_leg_geom", "right_ankle_geom", -1, 1,
           "hip_2", "ankle_2", "1 1 0", "-70 -30", aux_attr),
      _leg("back_leg", "aux_3_geom", "back_leg_geom", "third_ankle_geom", -1, -1,
           "hip_3", "ankle_3", "-1 1 0", "-70 -30", aux_attr),
      _leg("right_back_leg", "aux_4_geom", "rightback_leg_geom", "fourth_ankle_geom", 1, -1,
           "hip_4", "ankle_4", "1 1 0", "30 70", aux_attr),
  ])
  motors = "".join(
      f'<motor ctrllimited="true" ctrlrange="-{CTRL_LIMIT:g} {CTRL_LIMIT:g}" joint="{j}" gear="1"/>'
      for j in ("hip_4", "ankle_4", "hip_1", "ankle_1", "hip_2", "ankle_2", "hip_3", "ankle_3"))
  numerics = _numerics(solver)
  extent = max(layout.shape) * layout.scaling
  return f"""<mujoco model="ant_maze">
  <compiler angle="degree" inertiafromgeom="true"/>
  <option integrator="RK4" timestep="0.02" iterations="{solver.iterations}" ls_iterations="{solver.ls_iterations}"/>
  <custom>{numerics}</custom>
  <size memory="8M"/>
  <default>
    <joint armature="1" damping="1" limited="true"/>
    <geom conaffinity="0" contype="{ant_bits}" condim="3" density="5.0" friction="1 0.5 0.5" margin="0.01" rgba="0.8 0.6 0.4 1"{solimp}/>
  </default>
  <visual><global offwidth="640" offheight="480"/></visual>
  <asset>
    <texture builtin="gradient" height="100" rgb1="1 1 1" rgb2="0 0 0" type="skybox" width="100"/>
    <texture builtin="checker" height="100" name="texplane" rgb1="0 0 0" rgb2="0.8 0.8 0.8" type="2d" width="100"/>
    <material name="MatPlane" reflectance="0.2" shininess="1" specular="1" texrepeat="60 60" texture="texplane"/>
  </asset>
  <worldbody>
    <light cutoff="100" diffuse="1 1 1" dir="0 0 -1.3" directional="true" exponent="1" pos="0 0 20" specular=".1 .1 .1"/>
    <geom name="floor" type="plane" pos="0 0 0" size="{extent:g} {extent:g} 40" material="MatPlane" rgba="0.8 0.9 0.8 1" contype="{floor_bits[0]}" conaffinity="{floor_bits[1]}"/>
    <body name="torso" pos="0 0 {z0:g}">
      <camera name="track" mode="trackcom" pos="0 -12 12" xyaxes="1 0 0 0 1 1"/>
      <geom name="torso_geom" pos="0 0 0" size="0.25" type="sphere"/>
      <joint armature="0" damping="0" limited="false" margin="0.01" name="root" pos="0 0 0" type="free"/>{legs}
    </body>
    {maze.maze_worldbody_xml(layout, optimised, static_bits, block_bits)}
  </worldbody>
  <actuator>{motors}</actuator>
</mujoco>"""


def load(layout: maze.MazeLayout, optimised: bool = True,
         solver: SolverSettings | None = None) -> mujoco.MjModel:
  """Compile the ant maze model."""
  return mujoco.MjModel.from_xml_string(ant_maze_xml(layout, optimised, solver))


def colliding_geoms(model: mujoco.MjModel) -> list[str]:
  """Names of the ant geoms that take part in contacts."""
  torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso")
  out = []
  for g in range(model.ngeom):
    body = model.geom_bodyid[g]
    root = model.body_rootid[body]
    if root == torso and (model.geom_contype[g] or model.geom_conaffinity[g]):
      out.append(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g))
  return out
