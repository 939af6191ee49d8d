"""The ant's physics engines, named without loading them (``AntConfig.physics``): ``c``, MuJoCo's C
engine called from inside the jitted step (``c_physics.py``); ``mjx``, the MJX pipeline;
``auto``, c on a CPU and mjx on an accelerator (``ant_maze.default_physics``)."""

PHYSICS = ("auto", "c", "mjx")
