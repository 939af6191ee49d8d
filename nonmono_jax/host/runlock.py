"""One writer per run folder: an OS lock on ``OUT/.lock`` held for the whole run.

    with runlock.hold(out):            # raises Locked("... held by pid 1234 (host, command)")
      ...train, append metrics, save checkpoints...

``fcntl.flock`` is released by the kernel when the holder's file descriptor closes, whatever
the exit (return, exception, SIGKILL), so a lock of a dead process is never stale: the next
process simply gets it. The file's content (pid, host, start time, command) is only there to
say who holds it; it is rewritten by each new holder.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import os
import socket
import sys

NAME = ".lock"


class Locked(RuntimeError):
  """Another process holds the run folder."""


def _holder(path: str) -> str:
  try:
    with open(path) as f:
      who = json.load(f)
    return (f"pid {who['pid']} on {who['host']} since {who['since']} "
            f"({who['command']})")
  except (OSError, ValueError, KeyError, TypeError):
    return "another process"


@contextlib.contextmanager
def hold(out: str):
  """Holds ``out``'s lock until the block exits; raises Locked if another process has it."""
  path = os.path.join(out, NAME)
  fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
  try:
    try:
      fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
      raise Locked(f"{out} is in use by {_holder(path)}; one process at a time may write a "
                   f"run folder") from None
    who = {"pid": os.getpid(), "host": socket.gethostname(),
           "since": datetime.datetime.now().isoformat(timespec="seconds"),
           "command": " ".join(sys.argv)}
    os.ftruncate(fd, 0)
    os.pwrite(fd, json.dumps(who).encode(), 0)
    yield
  finally:
    os.close(fd)
