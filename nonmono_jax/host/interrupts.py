"""Ctrl-C and SIGTERM at any moment of a command: one line on stderr, exit code 1, and nothing
half-written.

    interrupts.install()                  # first thing in an entry module, before JAX loads
    ...imports, flags, checks, compiling for the memory check: nothing written yet...
    with interrupts.during_run(line):     # from the run folder's opening; line() says what is
      with interrupts.writing():          #   saved and how to continue
        ...config.json, a chunk's rows, its checkpoint...
      interrupts.check()                  # a safe point: raises the signal received, if any

During start-up (``install``, before ``during_run``) nothing is written, so a signal ends the
process at once: ``interrupted during start-up: nothing was written``. During the run a signal
is taken at the next safe point (``check``: after a write, after each chunk), where it raises
``KeyboardInterrupt`` (``Terminated`` for SIGTERM) for the command to say its line; a write
under way (``writing``) always finishes first. Python runs a signal handler only between
bytecodes of the main thread, so a signal that lands while the main thread is inside a long
call (XLA compiling, a chunk running, an import) waits for that call; and JAX runs callbacks
that swallow exceptions (its garbage-collection hook). So ``install`` also starts a watchdog
thread, woken by the signal itself (``signal.set_wakeup_fd``): if the main thread has not
reached a safe point ``GRACE_S`` after the signal and writes nothing, the watchdog writes the
line and ends the process. A second Ctrl-C ends it at once. Without ``install`` (the run
library in a notebook, tests) there is no watchdog and a signal waits for the next safe point.

This module imports nothing but the standard library.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sys
import threading
import time

GRACE_S = 2.0  # how long the watchdog lets the main thread reach a safe point
EXIT_INTERRUPTED = 1  # a Ctrl-C or SIGTERM ends a command with this code (docs/experiments.md)


class Terminated(KeyboardInterrupt):
  """SIGTERM (a batch scheduler's stop, ``kill``): handled as Ctrl-C is."""


_SIGNALS = {signal.SIGINT: KeyboardInterrupt, signal.SIGTERM: Terminated}
_NAMES = {KeyboardInterrupt: "interrupted", Terminated: "terminated (SIGTERM)"}


class _State:
  """What the handler, the watchdog and the main thread share (under ``lock``)."""

  def __init__(self):
    self.lock = threading.Lock()
    self.installed = False  # install() ran: start-up ends the process at once; a watchdog
    self.line = None  # during a run: () -> its one line, given the signal's description
    self.received: list = []  # the exception classes of the signals received, in order
    self.taken = False  # the main thread raised the signal: it says the line itself
    self.writes = 0  # depth of writing() sections under way
    self.said = False  # the interruption's line is written (once per process)
    self.sockets = ()  # the wakeup socket pair, kept open for the process's life


_state = _State()


def describe(exc: type) -> str:
  """``interrupted`` or ``terminated (SIGTERM)``."""
  return _NAMES.get(exc, "interrupted")


def install() -> None:
  """Handle SIGINT and SIGTERM from now on (start-up: end at once, one line) and start the
  watchdog. Call it first in an entry module's main, before the heavy imports."""
  if threading.current_thread() is not threading.main_thread() or _state.installed:
    return
  wake, woken = socket.socketpair()
  wake.setblocking(False)
  signal.set_wakeup_fd(wake.fileno(), warn_on_full_buffer=False)
  for sig in _SIGNALS:
    signal.signal(sig, _handler)
  _state.installed, _state.sockets = True, (wake, woken)
  threading.Thread(target=_watch, args=(woken,), name="interrupts", daemon=True).start()


def _handler(signum, frame) -> None:
  """In the main thread, between bytecodes: remember the signal; during start-up, end."""
  with _state.lock:
    _state.received.append(_SIGNALS[signum])
    starting = _state.installed and _state.line is None
  if starting:
    _end(f"error: {describe(_SIGNALS[signum])} during start-up: nothing was written")


def _watch(woken: socket.socket) -> None:
  """The watchdog: on each signal, end the process if the main thread cannot take it."""
  while True:
    try:
      data = woken.recv(64)
    except OSError:
      return
    if not data:
      return
    signals = [signal.Signals(b) for b in data if b in _SIGNALS]
    if signals:
      _on_signal(_SIGNALS[signals[-1]])


def _on_signal(exc: type) -> None:
  """Start-up: end now. A run: end unless the main thread takes it within GRACE_S (a write
  under way finishes first); a second signal ends at once."""
  with _state.lock:
    run_line = _state.line
    second = len(_state.received) > 1
  if run_line is None:
    _end(f"error: {describe(exc)} during start-up: nothing was written")
  deadline = time.monotonic() + (0.0 if second else GRACE_S)
  while True:
    with _state.lock:
      taken, writing = _state.taken, _state.writes > 0
    if taken and not second:
      return
    if time.monotonic() >= deadline and (not writing or second):
      break
    time.sleep(0.05)
  _end(run_line(exc))


def _end(line: str) -> None:
  """Write ``line`` (``say``) and end the process with ``EXIT_INTERRUPTED``."""
  try:
    sys.stdout.flush()
  except (OSError, ValueError):
    pass
  try:
    say(line, fresh_line=_isatty(sys.stderr))
  finally:
    os._exit(EXIT_INTERRUPTED)


def say(line: str, fresh_line: bool = False) -> None:
  """Write the interruption's ``line`` on stderr, unless one was written already (the main
  thread and the watchdog may both come to say it)."""
  with _state.lock:
    if _state.said:
      return
    _state.said = True
  try:
    sys.stderr.write(f"{chr(10) if fresh_line else ''}{line}\n")
    sys.stderr.flush()
  except (OSError, ValueError):
    os.write(2, f"{line}\n".encode(errors="replace"))


def _isatty(stream) -> bool:
  try:
    return stream.isatty()
  except (OSError, ValueError, AttributeError):
    return False


@contextlib.contextmanager
def during_run(line):
  """A run's stage: a signal is taken at the next safe point (``check``), or ended by the
  watchdog with ``line(exc)``, the run's one line. Handlers are installed for the block (and
  put back after) if ``install`` has not; a signal left over does not outlive the block."""
  if threading.current_thread() is not threading.main_thread():
    yield
    return
  previous = None if _state.installed else {s: signal.signal(s, _handler) for s in _SIGNALS}
  with _state.lock:
    _state.line, _state.taken, _state.said = line, False, False
    _state.received.clear()
  try:
    yield
  finally:
    with _state.lock:
      _state.line, _state.taken = None, False
      _state.received.clear()
    for sig, old in (previous or {}).items():
      signal.signal(sig, old)


@contextlib.contextmanager
def writing():
  """A write to the run folder that a signal must not cut: the signal waits for its end,
  where it is raised (``check``)."""
  with _state.lock:
    _state.writes += 1
  try:
    yield
  finally:
    with _state.lock:
      _state.writes -= 1
  check()


def check() -> None:
  """A safe point: raise the signal received during the run, if any (only in the main
  thread, outside a write)."""
  if threading.current_thread() is not threading.main_thread():
    return
  with _state.lock:
    if not _state.received or _state.writes or _state.line is None or _state.taken:
      return
    _state.taken = True
    exc = _state.received[0]
  raise exc()
