"""One run over several processes and machines: JAX's multi-process runtime.

    processes.join(coordinator="node0:8476", num_processes=2, process_id=0)   # before any JAX op
    processes.join()              # SLURM or Open MPI: detected by jax.distributed.initialize

After ``join`` every process sees the devices of all (``jax.devices()``), and the trainer's
lanes (seeds x variants) are sharded over all of them with the mesh it builds anyway
(``train.py``): each process steps its own lanes, with no communication inside a chunk.
Between chunks the host side needs a few small things from every process:

- ``gather(tree)``: per-lane arrays from every process, whole, on every process (each
  chunk's reduced metrics and the handful of counters its rows need: bytes per lane);
- ``agree(value)``: process 0's value on every process, for decisions all must take alike
  (stop for the time limit);
- ``writer()``: process 0 owns the run folder (``config.json``, the lock, ``metrics.csv``,
  the progress bar); the others write nothing there but their checkpoint shards (orbax).

Processes on one machine should each have their own cores: XLA:CPU sizes its thread pools
by the cores a process may use, and two processes whose pools share the same cores run at
0.7x of one process with two CPU devices (``benchmarks/processes.py``). Launchers do this
(``srun --cpu-bind=cores``, ``mpirun --bind-to core``, ``taskset``); the experiment command
does it for processes it knows share this machine (``experiments/cores.py``).

CPU processes exchange these through gloo (jax >= 0.5.1). A process that dies makes the next
exchange fail on the others (``jax_enable_recoverability`` keeps them alive to say so,
instead of the runtime aborting them with a C++ stack trace), and they raise
``ProcessLost``; one that stops answering (alive, silent) leaves the others waiting in the
exchange, and after ``HEARTBEAT_S`` without its heartbeats ``watch``'s thread ends them with
the same kind of line. Either way the run stops at its last checkpoint.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import threading
import time

import jax
import numpy as np
from jax._src import distributed
from jax.experimental import multihost_utils

HEARTBEAT_S = 60  # a process silent this long is dead (JAX's default: 100)
INIT_TIMEOUT_S = 300  # how long the processes wait for each other at the start


class ProcessLost(RuntimeError):
  """Another process of the run died or stopped answering."""


def join(coordinator: str | None = None, num_processes: int | None = None,
         process_id: int | None = None) -> None:
  """Joins the run's processes (``jax.distributed.initialize``): all three given, or none
  (detected on SLURM and Open MPI). Call it before JAX runs anything."""
  given = [x is not None for x in (coordinator, num_processes, process_id)]
  if any(given) and not all(given):
    raise ValueError("--coordinator, --num-processes and --process-id go together (or none "
                     "of them, on SLURM or Open MPI)")
  if num_processes is not None and not 0 <= process_id < num_processes:
    raise ValueError(f"--process-id must be in [0, {num_processes}), got {process_id}")
  if coordinator is not None:
    check_address(coordinator)
  jax.config.update("jax_enable_recoverability", True)
  try:
    jax.distributed.initialize(coordinator, num_processes, process_id,
                               initialization_timeout=INIT_TIMEOUT_S,
                               heartbeat_timeout_seconds=HEARTBEAT_S)
  except (RuntimeError, ValueError, IndexError) as e:  # IndexError: an address it cannot parse
    first = (str(e).strip().splitlines() or [type(e).__name__])[0]
    raise ValueError(f"--distributed: cannot join the run's processes ({first[:200]})") from None


def check_address(coordinator: str) -> None:
  """``--coordinator`` is HOST:PORT, the host without blanks, the port in 1-65535 (else the
  join would wait out its timeout on a port no process can open); a ValueError naming it."""
  host, sep, port = coordinator.rpartition(":")
  if not sep or not host or any(ch.isspace() for ch in host):
    raise ValueError(f"--coordinator must be HOST:PORT, got {coordinator!r}")
  if not port.isdigit() or not 1 <= int(port) <= 65535:
    raise ValueError(f"--coordinator's port must be in 1-65535, got {port!r}")


def watch(on_lost, every_s: float = 5.0) -> None:
  """Starts a thread that asks the runtime every ``every_s`` which processes are alive; when
  one is not (dead, or silent for ``HEARTBEAT_S``), ``on_lost(message)`` runs and this
  process ends with exit code 1. A process stuck in an exchange with a stopped (not dead)
  one would otherwise wait for ever: gloo has no deadline."""
  if count() == 1:
    return
  client, everyone = distributed.global_state.client, list(range(count()))

  def loop():
    while True:
      time.sleep(every_s)
      try:
        gone = sorted(set(everyone) - set(client.get_live_nodes(everyone)))
      except Exception as e:  # noqa: BLE001 - the runtime's service is gone (process 0 died)
        gone, why = None, (str(e).strip().splitlines() or [type(e).__name__])[0][:200]
      if gone == [] or _LEAVING:
        continue
      lost = f"process(es) {', '.join(map(str, gone))}" if gone else f"the runtime ({why})"
      _LOST.append(lost)
      with contextlib.suppress(Exception):
        on_lost(f"process {index()} of {count()} lost {lost}")
      sys.stdout.flush()
      sys.stderr.flush()
      os._exit(1)

  threading.Thread(target=loop, name="processes.watch", daemon=True).start()


def count() -> int:
  return jax.process_count()


def index() -> int:
  return jax.process_index()


def writer() -> bool:
  """Process 0, which owns the run folder (or the only process)."""
  return jax.process_index() == 0


_LOST = []  # set once an exchange failed: the others are not waited for again
_LEAVING = []  # set when the run ends: processes leaving are not lost


@contextlib.contextmanager
def lost_peers():
  """Turns a failed exchange with another process (the runtime's status errors: "UNKNOWN:
  Gloo AllGather failed: ... Connection closed by peer", "UNAVAILABLE: ...") into
  ``ProcessLost`` (one line)."""
  try:
    yield
  except (jax.errors.JaxRuntimeError, ValueError, RuntimeError) as e:
    first = (str(e).strip().splitlines() or [type(e).__name__])[0]
    if count() == 1 or not re.match(r"[A-Z_]+: ", first):
      raise
    _LOST.append(first)
    raise ProcessLost(f"process {index()} of {count()} lost the others "
                      f"({first[:200]})") from None


def gather(tree):
  """Per-lane arrays (leading lane axis, sharded over every process's devices) whole, as
  numpy, on every process."""
  if count() == 1:
    return jax.tree.map(np.asarray, tree)
  with lost_peers():
    return jax.tree.map(np.asarray, multihost_utils.process_allgather(tree, tiled=True))


def agree(value: bool) -> bool:
  """Process 0's ``value`` on every process."""
  if count() == 1:
    return value
  with lost_peers():
    return bool(multihost_utils.broadcast_one_to_all(np.asarray(value)))


def leave(exit_code: int, wait_s: float = 30.0) -> None:
  """The end of a multi-process run: every process waits for the others, then leaves the
  runtime; process 0, which serves it, last (a process that finds the service gone when it
  leaves is aborted by the runtime). After a lost process the others cannot leave in order
  (process 0's service may be gone with it): they end here, with ``exit_code``, their files
  already closed."""
  if count() == 1:
    return
  _LEAVING.append(True)
  if _LOST and not writer():
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(exit_code)
  if not _LOST:
    with contextlib.suppress(ProcessLost):
      barrier("run end")
  if writer():
    client = distributed.global_state.client  # jax has no public call for who is still in
    others = set(range(1, count()))
    deadline = time.monotonic() + wait_s
    while others & set(client.get_live_nodes(list(range(count())))) and \
        time.monotonic() < deadline:
      time.sleep(0.05)
  jax.distributed.shutdown()


def barrier(name: str) -> None:
  """Every process waits here for the others."""
  if count() > 1:
    with lost_peers():
      multihost_utils.sync_global_devices(name)
