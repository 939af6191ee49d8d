"""Generic checks of any config dataclass, by its type hints: finite floats, int32 ints.

    validation.check(config)            # raises ValueError("low.lr_actor must be finite, ...")
    validation.check(spec, flags=True)  # RunSpec: names as flags ("--episode-length")

The config dataclasses check their own ranges (``__post_init__``), but a comparison with NaN
is always false, so NaN and inf pass every bound written as ``x < lo``, and a Python int has no
bound at all while the jitted program stores it in an int32. This walks a dataclass
recursively (so fields added later are covered without a change here) and checks every leaf:

- ``float``: finite, unless the field says ``metadata={"infinite_ok": True}`` (inf allowed,
  NaN never), and within float32's range, in which the jitted program computes (a Python
  float of 1e39 is inf there);
- ``int``: within int32 (``bool`` is left alone);
- tuples and sequences of those: element-wise, named ``field[i]``.

Errors name the full dotted path (``top.ppo.lr_actor``).
"""

from __future__ import annotations

import dataclasses
import math
import typing

INT32_MAX = 2**31 - 1
INT32_MIN = -2**31
FLOAT32_MAX = 3.4028234663852886e38  # numpy.finfo(numpy.float32).max


def _name(prefix: str, field: str, flags: bool) -> str:
  return f"--{field.replace('_', '-')}" if flags else prefix + field


def check_value(name: str, value, infinite_ok: bool = False) -> None:
  """One leaf (or a tuple/list of leaves): finite float, int within int32."""
  if isinstance(value, (tuple, list)):
    for i, v in enumerate(value):
      check_value(f"{name}[{i}]", v, infinite_ok)
    return
  if isinstance(value, bool):
    return
  if isinstance(value, float):
    if math.isnan(value) or (math.isinf(value) and not infinite_ok):
      raise ValueError(f"{name} must be a finite number, got {value}")
    if math.isfinite(value) and abs(value) > FLOAT32_MAX:
      raise ValueError(f"{name} must fit in a float32 (|value| <= {FLOAT32_MAX:.4g}), got "
                       f"{value}")
  elif isinstance(value, int) and not INT32_MIN <= value <= INT32_MAX:
    raise ValueError(f"{name} must fit in an int32 (|value| <= {INT32_MAX}), got {value}")


def check(config, prefix: str = "", flags: bool = False) -> None:
  """Every leaf field of the dataclass ``config``, recursively; raises ValueError naming it."""
  hints = typing.get_type_hints(type(config))
  for f in dataclasses.fields(config):
    value = getattr(config, f.name)
    name = _name(prefix, f.name, flags)
    if dataclasses.is_dataclass(hints.get(f.name)) or dataclasses.is_dataclass(value):
      check(value, prefix + f.name + ".", flags)
    else:
      check_value(name, value, f.metadata.get("infinite_ok", False))

