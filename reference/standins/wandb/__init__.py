"""A stand-in for ``wandb`` that records what the code logs instead of sending it.

Every ``wandb.log(data, step=...)`` call is handed, as ``(data, step)`` with tensors and numpy
scalars turned into Python numbers, to each function in ``sinks`` (the harness adds one that
writes the run's JSONL and per-evaluation rows); ``calls`` keeps them too unless ``keep`` is
False. ``init`` records its arguments; nothing is sent anywhere.
"""

sinks = []
calls = []
keep = True
init_args = None
run = None


def _plain(value):
  """A tensor, numpy scalar or 0-d array as a Python number; other values unchanged."""
  if hasattr(value, "detach"):
    value = value.detach().cpu().numpy()
  if hasattr(value, "item") and getattr(value, "size", 1) == 1:
    return value.item()
  if hasattr(value, "tolist"):
    return value.tolist()
  return value


def log(data, step=None, commit=None, sync=None):
  """Record one logging call: its values (as plain numbers) and its step."""
  record = {key: _plain(value) for key, value in data.items()}
  step = None if step is None else int(step)
  if keep:
    calls.append((record, step))
  for sink in sinks:
    sink(record, step)


def init(*args, **kwargs):
  """Record the arguments; return a stand-in run object."""
  global init_args, run
  init_args = (args, kwargs)
  run = _Run()
  return run


def finish(*args, **kwargs):
  """Nothing to finish."""


def watch(*args, **kwargs):
  """Nothing to watch."""


class _Run:
  def log(self, data, step=None, **kwargs):
    log(data, step=step)

  def finish(self, *args, **kwargs):
    pass


class Video:
  """Accepted and dropped (the code's video logging is commented out)."""

  def __init__(self, *args, **kwargs):
    pass


Image = Video
config = {}
