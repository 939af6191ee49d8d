"""The ant's physics: its engines by name and what an engine is, without loading any of them
(the command's ``--physics`` choices are read from here before JAX loads).

    ENGINES = ("c", "mjx")          # AntConfig.physics: c_physics.CPhysics, mjx_physics.MjxPhysics
    PHYSICS = ("auto", "c", "mjx")  # --physics; a run's plan resolves auto (plan.run_physics)

``c``, MuJoCo's C engine called from inside the jitted step (``c_physics.py``); ``mjx``, the
MJX pipeline (``mjx_physics.py``). An env builds its engine once, from its config
(``ant_maze.AntMazeEnv``), and steps whichever it is through the ``Physics`` protocol.
"""

from __future__ import annotations

from typing import Any, Protocol

ENGINES = ("c", "mjx")
PHYSICS = ("auto", *ENGINES)


class Physics(Protocol):
  """An engine stepping one MuJoCo model from inside jit; its state has ``qpos`` and ``qvel``."""

  def init(self, qpos: Any, qvel: Any) -> Any:
    """The state at ``qpos``, ``qvel``, at rest in time 0."""

  def step(self, state: Any, ctrl: Any) -> Any:
    """The state after the engine's frames (an env step) with ``ctrl`` held."""

  def unstable(self, state: Any) -> Any:
    """1.0 if the step that made ``state`` left the simulation unstable, else 0.0."""
