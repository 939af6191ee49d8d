"""A lane's numbers: the config fields declared ``traced``, as the pytree the jitted step reads.

A config field is static (it builds the program: sizes, c, horizons, which learners and which
switch exist) unless its declaration says otherwise, once, where the field is declared:

    gamma: float = traced(0.99)              # in td3.TD3Config: a number of the lane
    reward_mod: bool = traced(True)          # a 0/1 weight (exact in float32 at 0 and 1)

Everything else is derived from that declaration:

    paths(config)           ("top.alpha", ..., "low.gamma", ...): the traced fields by dotted path
    of(config)              Numbers: those fields as float32 arrays; hp.top.alpha, hp.low.gamma
    static_key(config)      the config with its traced fields at their declared defaults:
                            configs with equal keys build one program (they can be its lanes)
    stack(configs)          Numbers with a leading variant axis

    check_group(configs)    their one static key, or a ValueError naming the fields where they
                            differ

The trainer always passes a lane's ``Numbers`` as an argument (``train.py``): one program path,
so a variant run alone computes bit for bit what it computes as a lane of a group. Adding a
traced number is one line: declare the field with ``traced(default)`` and read ``hp.<path>``
where the jitted code uses it.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Iterator, Mapping, Sequence

import jax
import numpy as np

from nonmono_jax.core.config import TRACED, differences
from nonmono_jax.core.config import traced  # noqa: F401 - declared with the config (no JAX)


def paths(config, prefix: str = "") -> Iterator[str]:
  """The dotted paths of ``config``'s traced fields, nested configs included."""
  for f in dataclasses.fields(config):
    value = getattr(config, f.name)
    if f.metadata.get(TRACED):
      yield prefix + f.name
    elif dataclasses.is_dataclass(value):
      yield from paths(value, f"{prefix}{f.name}.")


@jax.tree_util.register_pytree_node_class
class Numbers:
  """Traced numbers by dotted path, a pytree; ``hp.low`` is the Numbers under ``low.``,
  ``hp.low.gamma`` the array."""

  __slots__ = ("_values",)

  def __init__(self, values: Mapping[str, Any]):
    object.__setattr__(self, "_values", dict(values))

  def __getattr__(self, name: str):
    values = object.__getattribute__(self, "_values")
    if name in values:
      return values[name]
    prefix = name + "."
    sub = {k[len(prefix):]: v for k, v in values.items() if k.startswith(prefix)}
    if not sub:
      raise AttributeError(f"no traced number {name!r} (traced: {', '.join(values)})")
    return Numbers(sub)

  def __setattr__(self, name, value):
    raise AttributeError("Numbers are immutable")

  def tree_flatten(self):
    keys = tuple(sorted(self._values))
    return [self._values[k] for k in keys], keys

  @classmethod
  def tree_unflatten(cls, keys, leaves):
    return cls(dict(zip(keys, leaves)))

  def __repr__(self):
    return f"Numbers({self._values!r})"


def of(config) -> Numbers:
  """The traced fields of ``config`` (any config dataclass) as float32 arrays."""
  get = lambda path: functools.reduce(getattr, path.split("."), config)
  return Numbers({p: np.asarray(get(p), np.float32) for p in paths(config)})


def static_key(config):
  """``config`` with each traced field at the default its declaration gives: configs with
  equal keys build one program."""
  changes = {}
  for f in dataclasses.fields(config):
    value = getattr(config, f.name)
    if f.metadata.get(TRACED):
      changes[f.name] = f.default
    elif dataclasses.is_dataclass(value):
      changes[f.name] = static_key(value)
  return dataclasses.replace(config, **changes)


def stack(configs: Sequence) -> Numbers:
  """The Numbers of each config stacked on a leading variant axis."""
  return jax.tree.map(lambda *xs: np.stack(xs).astype(np.float32), *[of(c) for c in configs])


def check_group(configs):
  """The one static key (``static_key``) of configs that run as lanes of one program; a
  ValueError naming the fields where they differ."""
  if not configs:
    raise ValueError("a group needs at least one config")
  key = static_key(configs[0])
  for i, c in enumerate(configs[1:], 1):
    other = static_key(c)
    if other != key:
      raise ValueError(f"variant {i} cannot share variant 0's program: they differ in "
                       f"{', '.join(differences(key, other))} (not traced)")
  return key
