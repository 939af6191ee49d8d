"""Imported first by the modules that import brax: ``mujoco.mjx`` prints a line about its
optional warp backend when it is first imported; this imports it with that line swallowed."""

import contextlib
import io

with contextlib.redirect_stdout(io.StringIO()):
  from mujoco import mjx  # noqa: F401
