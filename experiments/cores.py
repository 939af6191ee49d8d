"""Each process of a run on one machine its own cores, before JAX is imported.

XLA:CPU and the libraries JAX loads size their thread pools by the cores a process may use
when they start. Processes of one ``--distributed`` run on the same machine whose pools share
all its cores slow each other down (2 processes x 1 CPU device on 2 cores ran at 0.7x of 1
process x 2 devices; pinned before the imports, 0.83x: ``benchmarks/processes.py``). So
``experiments.cli`` imports this module first: when the flags say every process of the run
is on this machine (``--coordinator`` on localhost or this host) and nothing has pinned this
one yet, process I of N takes the I-th of N equal shares of the cores. Launchers that place
processes on several machines pin them themselves (``srun --cpu-bind=cores``, ``mpirun
--bind-to core``); this module then leaves them alone.
"""

from __future__ import annotations

import os
import socket


def _flag(argv: list[str], name: str) -> str | None:
  for i, arg in enumerate(argv):
    if arg == name and i + 1 < len(argv):
      return argv[i + 1]
    if arg.startswith(name + "="):
      return arg.split("=", 1)[1]
  return None


def _local(host: str) -> bool:
  if host in ("localhost", "::1") or host.startswith("127."):
    return True
  try:
    return host in (socket.gethostname(), socket.getfqdn()) or \
        socket.gethostbyname(host) == socket.gethostbyname(socket.gethostname())
  except OSError:
    return False


def share(argv: list[str]) -> tuple[int, ...] | None:
  """Pins this process to its share of the cores if ``argv`` says the run's processes are
  all on this machine; the cores it took, or None."""
  if "--distributed" not in argv or not hasattr(os, "sched_setaffinity"):
    return None
  coordinator, n, i = (_flag(argv, f) for f in ("--coordinator", "--num-processes",
                                                 "--process-id"))
  try:
    n, i = int(n), int(i)
  except (TypeError, ValueError):
    return None
  cores = sorted(os.sched_getaffinity(0))
  if coordinator is None or not _local(coordinator.rsplit(":", 1)[0]) or not 0 <= i < n \
      or n < 2 or len(cores) < n or len(cores) < (os.cpu_count() or 0):
    return None  # not all here, or already pinned (fewer cores than the machine's)
  k = len(cores) // n
  mine = tuple(cores[i * k:(i + 1) * k])
  os.sched_setaffinity(0, mine)
  return mine
