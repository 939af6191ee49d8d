"""How g_expl_mode is chosen: one interface, one file per chooser; the only thing methods
differ in. By ``AgentConfig.switch`` (``config.CHOOSERS``, the registry):

    "none"         fixed.py    HIRO: always TD3, no starting mode
    "top"          top.py      ours: the Top PPO picks a mode per Top horizon; RANDOM in the
                               starting mode
    "homeostasis"  trigger.py  Ref:Uniform / Ref:PPO: Pislar et al.'s informed trigger at Middle
                               decisions; the explore mode in the starting mode

A chooser (the ``ModeChooser`` protocol) owns its state (``SeedState.chooser``, per env) and
four pure methods:

    init(keys, obs, middle_params) -> (state, mode)              the first segments' modes (E,)
    accumulate(state, reward, success) -> state                  every env step (R_m, Done_m)
    decide(state, mode, decision, keys, hp) -> (state, mode, metrics)  at a Middle decision
    update(state, t, live, s_e, hp) -> (state, metrics)          its learner, on its own clock

``hp`` is the lane's ``lanes.Numbers`` (the Top's alpha, S_O and its two switches, the
trigger's rho): numbers read at run time, so variants of one program differ in them.

``keys`` are the agent's named keys (``agent.InitKeys`` / ``agent.StepKeys``): the Top uses
``top`` and ``horizon``, the trigger ``switch``. The starting mode runs after warm-up until
``live_from``; then the chooser's own choices start.

A new chooser is its file here, with ``make(config, obs_size, target, value)`` returning it,
and its entry in ``config.CHOOSERS`` (with its options, if it has any, declared in
``config.py``, which the command line reads without JAX).
"""

from __future__ import annotations

import importlib
from typing import Callable, Protocol

import jax
from flax import struct

from nonmono_jax.core import td3
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.lanes import Numbers


@struct.dataclass
class Decision:
  """What a Middle decision at the end of step ``t`` sees (per env where batched)."""

  t: jax.Array  # the global step that just ran (unbatched)
  episode_end: jax.Array  # the episode ended with this step (the envs are reset)
  obs: jax.Array  # (E, obs) s where the next segment starts
  s_c: jax.Array  # (E, obs) the finished segment's last state
  reward: jax.Array  # (E,) its Middle reward R_M
  middle: td3.TD3Params  # the Middle TD3 (the trigger's V)


class ChooserState(Protocol):
  """A chooser's state (a flax struct, per env): it says which learners it holds."""

  def learner_params(self) -> dict: ...


class ModeChooser(Protocol):
  """What a chooser is (module doc): its constants and four pure functions."""

  name: str  # its switch: "none", "top" or "homeostasis" (config.CHOOSERS)
  starting_mode: int
  live_from: int  # warm-up + the starting mode: the first step of the chooser's own choices

  def init(self, keys, obs, middle_params) -> tuple[ChooserState, jax.Array]: ...
  def accumulate(self, state: ChooserState, reward, success) -> ChooserState: ...
  def decide(self, state: ChooserState, mode, decision: Decision, keys,
             hp: Numbers) -> tuple[ChooserState, jax.Array, dict]: ...
  def update(self, state: ChooserState, t, live, s_e, hp: Numbers
             ) -> tuple[ChooserState, dict]: ...


def make_chooser(config: AgentConfig, obs_size: int, target, value: Callable) -> ModeChooser:
  """The chooser of ``config.switch``, from its module's ``make``; ``value`` is the Middle's
  V (the trigger's signal)."""
  module = importlib.import_module(f"{__name__}.{config.chooser.module}")
  return module.make(config, obs_size, target, value)
