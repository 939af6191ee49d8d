"""The agent's configuration: frozen dataclasses whose defaults are the paper's (docs/spec.md).

    AgentConfig            the hierarchy, the method's switch, the schedule, the learners
      .top: TopConfig      Top PPO: horizon, alpha, S_O, the starting mode, loss modification
      .homeostasis         HomeostasisConfig: Pislar et al.'s trigger (Ref:*): rho, explore period
      .low, .middle        TD3Config of the Low and Middle TD3
      .middle_ppo          PPOConfig of the Middle PPO (Gaussian goals, decaying std)

A method (``methods.py``) is one of these configurations; every value is checked here, before
anything compiles, with a message that names the field. This module imports no JAX: the
command line reads it to build its flags and answer ``--help`` at once.

Each field is declared once, where its class declares it: its type, its default, whether it
is a lane's traced number (``traced(default)``, ``lanes.py``), its allowed values
(``choice(default, allowed)``, checked by ``check_choices``) and, in the comment beside or
above it, what it means (the command line's help text, ``experiments/flags.py``).

One way to change a configuration: dotted paths (``override``), as presets, methods, the
command line, tests and benchmarks all do; ``config_from_dict`` inverts ``folder.to_jsonable`` so
that a run is loaded from its ``config.json``:

    config = override(AgentConfig(), {"top.alpha": (0, 0.4, 0.7), "middle.target_smoothing": True})
    config = config_from_dict(saved, base)      # saved: the JSON of a config; base: missing fields
    differences(config, other)                  # ["top.alpha", ...]
"""

from __future__ import annotations

import collections.abc
import dataclasses
import typing
from typing import Any, Callable, Mapping, Sequence

from nonmono_jax.core import validation

# The modes of the Top level, g_expl_mode, in the order of the paper's alpha and S_O tuples:
# TD3 (exploit), PPO and RANDOM (explore). ``hierarchy`` holds the formulas that use them.
TD3, PPO, RANDOM = 0, 1, 2
MODES = ("TD3", "PPO", "RANDOM")
GOAL_SIZE = 3  # goals are xyz offsets: the first 3 observation entries of every env

EXPLORE_MODES = ("ppo", "random")  # the explore mode of the homeostasis switch
RANDOM_GOALS = ("uniform", "gaussian")  # ours uniform; the paper's code clip(randn * range)
RELABELS = ("store", "sample")  # the paper's code: once at store, Low target actor; HIRO: per batch
PPO_SAMPLES = ("own", "executed")  # what the Middle PPO stores for segments other modes ran
# Where the paper's code made a choice that this project first made otherwise
# (docs/fidelity.md): the first value is the earlier one, kept as the default so that every
# earlier run is what it was; the Ant presets (methods.py) take the code's, the second.
LOW_DONE_GOALS = ("next", "current")  # Low done ||g|| <= 1.5 of g' = h(s, g, s') or of g
SCORED_STATES = ("next", "current")  # training's task reward and success: on s' or on s
EPISODE_STARTS = ("reset", "last")  # an episode's first goal and mode: from the reset state
#                                      or from the last state before the reset
MIDDLE_TD3_INPUTS = ("state_target", "state")  # the Middle TD3 actor's input (critic: + goal)
# The Middle TD3's s_0 in an episode's first segment under episode_start="last": the last state
# before the reset (where the goal was chosen) or the reset state (the code: its sequence is
# cleared at the reset; the Middle PPO and the Top keep the last state)
FIRST_SEGMENT_STATES = ("last", "reset")
WARMUP_GOALS = ("uniform", "gaussian")  # warm-up goals: U(+-range) or the code's clip(randn*range)
# Which evaluation gives S_E (the Top's loss reads it; evaluate.py): the Middle TD3's goal held
# c steps with the goal transition, or the code's Middle TD3 re-queried at every env step
EVAL_GOALS = ("held", "requery")
EVAL_KINDS = EVAL_GOALS + ("ppo",)
# Network initialisation (networks.py): flax's lecun-uniform weights and zero biases, or
# PyTorch's nn.Linear default (weights and biases U(+-1/sqrt(fan_in))), the paper's code's
INITS = ("lecun", "torch")
MEAN_HEADS = ("linear", "tanh")  # the Gaussian PPO's mean head (ppo.py)
CADENCES = ("periods", "code")  # when the homeostasis trigger checks (modes/trigger.py)
TARGET_NOISES = ("sample", "batch")  # TD3's target smoothing: a draw per sample, or one per batch
VALUE_WEIGHTINGS = ("sample", "batch")  # PPO's loss weight on each sample's value error, or on
#                                         the rollout's mean value loss (the paper's PPOM)
RELABEL_TIES = ("original", "random")  # an exact tie of HIRO's correction: the original goal wins,
#                                        or (the code) its first candidate, a random one

TRACED, CHOICES = "traced", "choices"  # the metadata keys of the two declarations below


# --- the mode choosers: how g_expl_mode is chosen (AgentConfig.switch) ------------------------

@dataclasses.dataclass(frozen=True)
class Chooser:
  """What the configuration knows of one way to choose g_expl_mode: its code, the fields it
  alone reads, and what the rest of the agent needs of it. Its state and functions are
  ``nonmono_jax/core/modes/<module>.py`` (``modes.make_chooser`` imports it by this name)."""

  module: str  # its file in nonmono_jax/core/modes/
  owns: tuple[str, ...] = ()  # dotted fields (or prefixes) that only this chooser reads
  also_reads: tuple[str, ...] = ()  # fields another chooser owns that it reads too
  horizon: str = "c"  # the field of the horizon that episodes must hold whole
  # whether the agent has a Middle PPO, and which of its own fields a config leaves unread
  middle_ppo: Callable[[Any], bool] = lambda config: False
  unread: Callable[[Any], tuple[str, ...]] = lambda config: ()


CHOOSERS = {
    "none": Chooser("fixed"),  # HIRO: always TD3
    # ours: the Top PPO picks a mode per Top horizon (alpha unread without the reward mod)
    "top": Chooser("top", owns=("top",), horizon="top.horizon", middle_ppo=lambda c: True,
                   unread=lambda c: () if c.top.reward_mod else ("top.alpha",)),
    # Ref:Uniform and Ref:PPO: Pislar et al.'s informed trigger; its starting phase is the
    # Top's starting mode (top.starting_steps)
    "homeostasis": Chooser("trigger", owns=("homeostasis", "explore_mode"),
                           also_reads=("top.starting_steps",),
                           middle_ppo=lambda c: c.explore_mode == "ppo"),
}
SWITCHES = tuple(CHOOSERS)  # "none" (HIRO), "top" (ours), "homeostasis" (Ref:Uniform, Ref:PPO)


def _under(path: str, prefix: str) -> bool:
  return path == prefix or path.startswith(prefix + ".")


def traced(default) -> Any:
  """A dataclass field whose value is a lane's number (a float, a bool as 0/1, or a tuple of
  floats), read by the jitted step from ``lanes.Numbers`` rather than compiled in."""
  return dataclasses.field(default=default, metadata={TRACED: True})


def choice(default, allowed: Sequence[str]) -> Any:
  """A string field (or a tuple of strings) whose values are among ``allowed``."""
  return dataclasses.field(default=default, metadata={CHOICES: tuple(allowed)})


def check_choices(config, prefix: str = "") -> None:
  """Every ``choice`` field of ``config`` (not nested ones) holds allowed values."""
  for f in dataclasses.fields(config):
    allowed = f.metadata.get(CHOICES)
    value = getattr(config, f.name)
    if allowed is None:
      continue
    for v in (value if isinstance(value, tuple) else (value,)):
      if v not in allowed:
        raise ValueError(f"{prefix}{f.name} must be one of {', '.join(allowed)}; got {v!r}")


def _check_triple(name, values, lo=None, hi=None):
  if len(values) != len(MODES):
    raise ValueError(f"{name} must have {len(MODES)} entries "
                     f"(one per mode {', '.join(MODES)}), got {values}")
  for v in values:
    if (lo is not None and v < lo) or (hi is not None and v > hi):
      bound = (f">= {lo}" if hi is None else f"<= {hi}" if lo is None else f"in [{lo}, {hi}]")
      raise ValueError(f"{name} entries must be {bound}, got {values}")


def _check_multiple(name, value, of_name, of):
  if value < 1 or value % of:
    raise ValueError(f"{name} must be a positive multiple of {of_name} ({of}), got {value}")


# --- the learners ------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class TD3Config:
  """TD3 hyperparameters; defaults are the paper's (docs/spec.md, section 2; both levels)."""

  hidden: Sequence[int] = (300, 300)  # hidden layer sizes of the actor and both critics
  lr_actor: float = traced(1e-4)  # Adam learning rate of the actor
  lr_critic: float = traced(1e-3)  # Adam learning rate of the critics
  gamma: float = traced(0.99)  # discount per step of this level
  tau: float = traced(5e-3)  # Polyak rate of the target networks
  batch_size: int = 100  # transitions per update
  policy_noise: float = traced(0.2)  # target smoothing noise std (absolute, as the HIRO port)
  noise_clip: float = traced(0.5)  # the target smoothing noise is clipped to +-noise_clip
  policy_delay: int = 1  # the paper's code: policy_freq = 1 (TD3's paper: 2)
  expl_noise: float = traced(1.0)  # behaviour noise std before clipping (Low: N(0, 1) on torques)
  buffer_size: int = 200_000  # a ring; the run presets size it to the run (never evicts)
  target_smoothing: bool = True  # TD3's target policy smoothing (ours' Middle: off)
  # the smoothing noise drawn per sample, or (the code) once per batch, shared by every sample
  target_noise: str = choice("sample", TARGET_NOISES)
  init: str = choice("lecun", INITS)  # network initialisation: "torch" is the paper's code

  def __post_init__(self):
    for name in ("lr_actor", "lr_critic", "tau", "gamma"):
      v = getattr(self, name)
      if not 0 < v <= 1:
        raise ValueError(f"{name} must be in (0, 1], got {v}")
    for name in ("batch_size", "policy_delay", "buffer_size"):
      if getattr(self, name) < 1:
        raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
    for name in ("policy_noise", "noise_clip", "expl_noise"):
      if getattr(self, name) < 0:
        raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
    if not self.hidden or any(h < 1 for h in self.hidden):
      raise ValueError(f"hidden must be positive layer sizes, got {self.hidden}")
    check_choices(self)


@dataclasses.dataclass(frozen=True)
class PPOConfig:
  """PPO hyper-parameters; the defaults are the paper's (and the port's) numbers."""

  hidden: Sequence[int] = (300, 300)  # hidden layer sizes of the actor and the critic (tanh)
  lr_actor: float = traced(3e-4)  # Adam learning rate of the actor
  lr_critic: float = traced(1e-3)  # Adam learning rate of the critic
  gamma: float = traced(0.99)  # discount of the Monte Carlo returns, per decision
  clip: float = traced(0.2)  # the ratio's clip range, 1 +- clip
  k_epochs: int = 10  # full-batch epochs over each rollout
  entropy_coef: float = traced(0.01)  # weight of the entropy bonus
  value_coef: float = traced(0.5)  # weight of the critic's loss
  discrete: bool = False  # a categorical policy (the Top's 3 modes) instead of a Gaussian
  std_init: float = 0.6  # the Gaussian's std at the start (in goal units with a linear head)
  std_decay: float = 0.05  # the std drops by this much every std_decay_every steps
  std_decay_every: int = 250_000  # env steps between two std decays
  std_min: float = 0.1  # the std decays no lower
  # the Gaussian's mean: "linear" (the paper's code) or "tanh" (scaled by the action range)
  mean_head: str = choice("linear", MEAN_HEADS)
  # The std schedule's first decay at step 0 (the paper's code: its t % 250K == 0 fires at
  # t = 0 too, so the Middle's std is 0.55 on [0, 250K)); False: std_init until the first period
  decay_at_start: bool = False
  init: str = choice("lecun", INITS)  # network initialisation: "torch" is the paper's code
  # the loss weight (Top: 1 +- S_E) on each sample's value error, or (the code) on the
  # rollout's mean value loss added to every sample's loss (ppo.py)
  value_weighting: str = choice("sample", VALUE_WEIGHTINGS)

  def __post_init__(self):
    object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
    if not self.hidden or min(self.hidden) <= 0:
      raise ValueError(f"hidden must be non-empty positive sizes, got {self.hidden}")
    for name in ("lr_actor", "lr_critic"):  # the same bounds as TD3's (TD3Config)
      if not 0 < getattr(self, name) <= 1:
        raise ValueError(f"{name} must be in (0, 1], got {getattr(self, name)}")
    if not 0 < self.gamma <= 1:
      raise ValueError(f"gamma must be in (0, 1], got {self.gamma}")
    if not 0 < self.clip < 1:
      raise ValueError(f"clip must be in (0, 1), got {self.clip}")
    if self.k_epochs < 1:
      raise ValueError(f"k_epochs must be >= 1, got {self.k_epochs}")
    if self.entropy_coef < 0:
      raise ValueError(f"entropy_coef must be >= 0, got {self.entropy_coef}")
    if self.value_coef < 0:
      raise ValueError(f"value_coef must be >= 0, got {self.value_coef}")
    if self.std_init <= 0:
      raise ValueError(f"std_init must be positive, got {self.std_init}")
    if self.std_min <= 0 or self.std_min > self.std_init:
      raise ValueError(f"std_min must be in (0, std_init], got {self.std_min}")
    if self.std_decay < 0:
      raise ValueError(f"std_decay must be >= 0, got {self.std_decay}")
    if self.std_decay_every < 1:
      raise ValueError(f"std_decay_every must be >= 1, got {self.std_decay_every}")
    check_choices(self)


@dataclasses.dataclass(frozen=True)
class HomeostasisConfig:
  """The informed trigger's options (``modes/trigger.py``): the paper's Ref code decides at Middle
  decisions, so ``k`` and ``gamma`` are per Middle segment of c env steps."""

  rho: float = traced(0.01)  # target exploit -> explore switch rate per trigger check
  explore_steps: int = 100  # length of an explore period in env steps: intra(100)
  gamma: float = 0.99  # discount of the value promise, per Middle segment
  k: int = 30  # lookback of the value promise discrepancy, in Middle segments
  reset_stats: bool = True  # fresh homeostasis statistics after each explore period
  # "periods": explore_steps of explore, then k exploit segments to fill a fresh window before
  # the first check (intra(100)); "code": the paper's code, k explore segments per switch (and
  # k - 1 after the starting phase), a check right after them and at every exploit segment
  cadence: str = choice("periods", CADENCES)

  def __post_init__(self):
    if not 0 < self.rho <= 1:
      raise ValueError(f"rho must be in (0, 1], got {self.rho}")
    if self.explore_steps < 1:
      raise ValueError(f"explore_steps must be >= 1, got {self.explore_steps}")
    if not 0 < self.gamma <= 1:
      raise ValueError(f"gamma must be in (0, 1], got {self.gamma}")
    if self.k < 1:
      raise ValueError(f"k must be >= 1, got {self.k}")
    check_choices(self, "homeostasis.")


# --- the agent ---------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class TopConfig:
  """The Top level: PPO over g_expl_mode in (TD3, PPO, RANDOM), one choice per ``horizon``."""

  horizon: int = 50  # Top horizon, env steps
  # R_final = R_m + alpha[m] R_m, one per mode (TD3, PPO, RANDOM): larger, rarer mode
  alpha: tuple[float, float, float] = traced((0.0, 0.4, 0.7))
  # done_m = S_O_m >= S_O[m], one per mode (TD3, PPO, RANDOM)
  s_o: tuple[float, float, float] = traced((0.6, 0.6, 0.6))
  s_o_start: float = traced(0.9)  # S_O during the starting mode
  starting_steps: int = 250_000  # after warm-up, the Top is forced to RANDOM for this long
  train_every: int = 400  # Top PPO trains on the train_every / horizon latest Top transitions
  reward_mod: bool = traced(True)  # False: alpha = 0 (ablation; a 0/1 weight of alpha)
  loss_mod: bool = traced(True)  # False: no S_E term in the Top loss (ablation; 0/1 weight)
  ppo: PPOConfig = PPOConfig(discrete=True)  # the Top PPO (categorical over the 3 modes)

  def __post_init__(self):
    object.__setattr__(self, "alpha", tuple(float(a) for a in self.alpha))
    object.__setattr__(self, "s_o", tuple(float(s) for s in self.s_o))
    if self.horizon < 1:
      raise ValueError(f"top.horizon must be >= 1, got {self.horizon}")
    _check_triple("top.alpha", self.alpha, lo=-1.0)
    _check_triple("top.s_o", self.s_o, lo=0.0, hi=1.0)
    if not 0 <= self.s_o_start <= 1:
      raise ValueError(f"top.s_o_start must be in [0, 1], got {self.s_o_start}")
    if self.starting_steps < 0:
      raise ValueError(f"top.starting_steps must be >= 0, got {self.starting_steps}")
    _check_multiple("top.train_every", self.train_every, "top.horizon", self.horizon)
    if not self.ppo.discrete:
      raise ValueError("top.ppo must be discrete (the Top picks one of 3 modes)")

  @property
  def rollout_length(self) -> int:
    return self.train_every // self.horizon


@dataclasses.dataclass(frozen=True)
class AgentConfig:
  """The whole agent; the defaults are ours on Ant Push (docs/spec.md, sections 2 and 3)."""

  # how g_expl_mode is chosen: "none" (HIRO), "top" (ours), "homeostasis" (Ref:Uniform, Ref:PPO)
  switch: str = choice("top", SWITCHES)
  explore_mode: str = choice("ppo", EXPLORE_MODES)  # homeostasis only: the explore mode
  # the RANDOM mode's goals: uniform in the goal range, or the code's clipped Gaussian
  random_goal: str = choice("uniform", RANDOM_GOALS)
  # HIRO's goal relabelling: once at store (the paper's code) or per sampled batch
  middle_relabel: str = choice("store", RELABELS)
  # which candidate of HIRO's correction wins an exact tie: the original goal, or (the code)
  # its first candidate, a random one
  relabel_ties: str = choice("original", RELABEL_TIES)
  # what the Middle PPO's rollout stores for segments another mode ran: its own sample of a
  # goal, or the goal executed
  middle_ppo_sample: str = choice("own", PPO_SAMPLES)
  # the Low's done, ||g|| <= 1.5, of the next goal g' or (the code) of the current goal g
  low_done_goal: str = choice("next", LOW_DONE_GOALS)
  # training's task reward and success scored on s' or (the code) on s; evaluation scores s'
  scored_state: str = choice("next", SCORED_STATES)
  # an episode's first goal and mode from the reset state or (the code) from the last state
  # before the reset
  episode_start: str = choice("reset", EPISODE_STARTS)
  # the Middle TD3 actor's input: the state and the target, or (the code) the state alone
  middle_td3_input: str = choice("state_target", MIDDLE_TD3_INPUTS)
  # the Middle TD3's s_0 in an episode's first segment (with episode_start "last"): the last
  # state before the reset, or (the code) the reset state
  middle_td3_first_state: str = choice("last", FIRST_SEGMENT_STATES)
  # the warm-up's goals: uniform, or (the code) the clipped Gaussian (RANDOM's: random_goal)
  warmup_goal: str = choice("uniform", WARMUP_GOALS)
  # the evaluation that gives S_E: the Middle TD3's goal held c steps, or (the code) the
  # Middle TD3 re-queried at every env step
  eval_goal: str = choice("held", EVAL_GOALS)
  # evaluation kinds also run each time, for their columns only: "held", "requery", "ppo" (the
  # Middle PPO re-queried, the code's 'higher success rate'; where it exists); none: no values
  eval_extra: tuple[str, ...] = choice((), EVAL_KINDS)
  # PPO returns (Top and Middle PPO) also end at an episode's end (False) or only at their own
  # terminals, done_m and success (True, the code's: a return may run into the next episode)
  returns_cross_episodes: bool = False
  eval_target_networks: bool = True  # S_E of the target actors, as the paper's code
  c: int = 10  # Middle horizon: env steps per Middle goal
  goal_range: tuple[float, float, float] = (10.0, 10.0, 0.5)  # the goals' x, y, z bounds (+-)
  warmup_steps: int = 100_000  # random low actions and goals, no updates
  middle_goal_noise: float = traced(0.0)  # Gaussian noise on TD3 goals: HIRO 1, ours 0
  middle_ppo_every: int = 30  # Middle PPO trains on its latest middle_ppo_every / c transitions
  eval_every: int = 10_000  # S_E of Middle TD3 + Low TD3, every eval_every env steps
  eval_episodes: int = 50  # episodes per evaluation (S_E is their success rate)
  num_envs: int = 1  # envs per seed (paper: 1)
  low_updates: int = 1  # Low TD3 updates per (vector) env step
  middle_updates: int = 1  # Middle TD3 updates per Middle horizon
  top: TopConfig = TopConfig()  # the Top PPO that picks g_expl_mode per Top horizon (ours)
  # Pislar et al.'s informed trigger between TD3 and one explore mode (Ref:Uniform, Ref:PPO)
  homeostasis: HomeostasisConfig = HomeostasisConfig()
  low: TD3Config = TD3Config()  # the Low TD3: torques every env step toward the Middle's goal
  middle: TD3Config = TD3Config(target_smoothing=False)  # the Middle TD3: a goal every c steps
  middle_ppo: PPOConfig = PPOConfig()  # the Middle PPO: the PPO mode's goals (Gaussian)

  def __post_init__(self):
    object.__setattr__(self, "goal_range", tuple(float(g) for g in self.goal_range))
    object.__setattr__(self, "eval_extra", tuple(self.eval_extra))
    check_choices(self)
    if self.c < 1:
      raise ValueError(f"c must be >= 1, got {self.c}")
    if len(self.goal_range) != GOAL_SIZE:
      raise ValueError(f"goal_range must have {GOAL_SIZE} entries (x, y, z), "
                       f"got {self.goal_range}")
    if any(r < 0 for r in self.goal_range):
      raise ValueError(f"goal_range must be >= 0, got {self.goal_range}")
    if self.warmup_steps < 0:
      raise ValueError(f"warmup_steps must be >= 0, got {self.warmup_steps}")
    for name in ("eval_every", "eval_episodes", "num_envs", "low_updates", "middle_updates"):
      if getattr(self, name) < 1:
        raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
    if self.middle_goal_noise < 0:
      raise ValueError(f"middle_goal_noise must be >= 0, got {self.middle_goal_noise}")
    _check_multiple("middle_ppo_every", self.middle_ppo_every, "c", self.c)
    if self.top.horizon % self.c:
      raise ValueError(f"top.horizon ({self.top.horizon}) must be a multiple of c ({self.c})")
    if self.homeostasis.explore_steps % self.c:
      raise ValueError(f"homeostasis.explore_steps ({self.homeostasis.explore_steps}) must be "
                       f"a multiple of c ({self.c}): the switch acts at Middle decisions")
    if self.middle_ppo.discrete:
      raise ValueError("middle_ppo must be Gaussian (discrete=False)")

  @property
  def chooser(self) -> Chooser:
    """The chooser of ``switch`` (``CHOOSERS``)."""
    return CHOOSERS[self.switch]

  @property
  def uses_middle_ppo(self) -> bool:
    return self.chooser.middle_ppo(self)

  def reads(self, path: str) -> bool:
    """Whether the agent this config builds reads the field at dotted ``path``: a chooser's
    fields only with that chooser (``CHOOSERS``: the Top's with switch "top", alpha only with
    the reward modification; the trigger's with "homeostasis"), the Middle PPO's only where it
    exists. A sweep of a field a method does not read would run identical lanes
    (``plan.new_run`` drops it)."""
    mine = self.chooser
    if any(_under(path, f) or _under(f, path) for f in mine.also_reads):
      return True
    unread = [f for c in CHOOSERS.values() if c is not mine for f in c.owns]
    unread += mine.unread(self)
    if not self.uses_middle_ppo:
      unread += ["middle_ppo", "middle_ppo_every"]
    return not any(_under(path, u) for u in unread)

  @property
  def middle_rollout_length(self) -> int:
    return self.middle_ppo_every // self.c

  @property
  def first_eval_steps(self) -> int:
    """Steps after which the first evaluation has run (the first multiple of eval_every past
    warm-up: evaluations run after step t when (t + 1) % eval_every == 0 and t >= warm-up)."""
    return -(-(self.warmup_steps + 1) // self.eval_every) * self.eval_every

  def check_env(self, episode_length: int) -> None:
    """An episode of ``episode_length`` steps holds whole Middle (and the chooser's) horizons."""
    name = self.chooser.horizon
    horizon = get(self, name)
    if episode_length % horizon:
      raise ValueError(f"episode_length ({episode_length}) must be a multiple of {name} "
                       f"({horizon}): horizons end with episodes")


# --- one way to override: dotted paths --------------------------------------------------------

def merge(*layers: Mapping[str, Any]) -> dict:
  """Dotted override dicts, later layers winning; a later whole value (``"low": cfg``) also
  drops the earlier paths under it (``"low.hidden"``), which it replaces."""
  out: dict = {}
  for layer in layers:
    for path, value in layer.items():
      for old in [k for k in out if k.startswith(path + ".")]:
        del out[old]
      out[path] = value
  return out


def override(config, overrides: Mapping[str, Any], prefix: str = ""):
  """``config`` with the dotted paths replaced: ``{"top.alpha": (0, 0.4, 0.7), "c": 5}``.

  Each dataclass level is replaced once with all its changes, so fields checked together
  (``c`` and ``top.horizon``) may change together; a whole value (``"low": TD3Config(...)``)
  is applied before the paths under it. Lists become tuples. Errors are ValueErrors naming the
  full dotted field (``low.lr_actor must be ...``, ``unknown TopConfig field 'top.x'``).
  """
  names = {f.name for f in dataclasses.fields(config)}
  whole, nested = {}, {}
  for path, value in flatten(overrides).items():
    head, _, rest = path.partition(".")
    if head not in names:
      raise ValueError(f"unknown {type(config).__name__} field {prefix + path!r}; valid: "
                       f"{', '.join(sorted(names))}")
    if rest:
      nested.setdefault(head, {})[rest] = value
    else:
      value = _tuples(value)
      if not dataclasses.is_dataclass(value):
        _check_type(prefix + head, value, typing.get_type_hints(type(config))[head])
        validation.check_value(prefix + head, value)
      whole[head] = value
  changes = dict(whole)
  for head, paths in nested.items():
    inner = whole.get(head, getattr(config, head))
    if not dataclasses.is_dataclass(inner):
      raise ValueError(f"{prefix + head} is not a config with fields "
                       f"(given {', '.join(prefix + head + '.' + p for p in paths)})")
    changes[head] = override(inner, paths, prefix + head + ".")
  return _replace(config, changes, prefix)


_KINDS = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}


def _check_type(name: str, value, hint) -> None:
  """A leaf's value has its field's type (a hand-edited config.json may say "8" for 8):
  ints are ints (not bools), floats are numbers, sequences hold their element type."""
  origin = typing.get_origin(hint)
  if origin in (tuple, list, collections.abc.Sequence):
    if not isinstance(value, tuple):
      raise ValueError(f"{name} must be a list, got {value!r}")
    elem = typing.get_args(hint)[0]
    for i, v in enumerate(value):
      _check_type(f"{name}[{i}]", v, elem)
    return
  ok = {int: lambda v: isinstance(v, int) and not isinstance(v, bool),
        float: lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
        bool: lambda v: isinstance(v, bool), str: lambda v: isinstance(v, str)}.get(hint)
  if ok is not None and not ok(value):
    raise ValueError(f"{name} must be {_KINDS[hint]}, got {value!r}")


def _tuples(value):
  return tuple(_tuples(v) for v in value) if isinstance(value, (list, tuple)) else value


def _replace(config, changes: dict, prefix: str):
  """``dataclasses.replace``; a nested config's own check names its field without the path
  (``lr_actor must be ...``): re-raised with the full dotted name."""
  try:
    return dataclasses.replace(config, **changes)
  except ValueError as e:
    msg = str(e)
    raise ValueError(msg if not prefix or msg.startswith(prefix.split(".")[0] + ".")
                     else prefix + msg) from None
  except TypeError as e:  # a value of the wrong kind (a string where a number goes)
    raise ValueError(f"{prefix}{e}") from None


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict:
  """``{"top": {"alpha": [...]}}`` (a config's JSON, or old nested overrides) -> dotted paths."""
  out = {}
  for name, value in nested.items():
    if isinstance(value, Mapping):
      out.update(flatten(value, prefix + name + "."))
    else:
      out[prefix + name] = value
  return out


def config_from_dict(data: Mapping[str, Any], base):
  """The config whose JSON (``folder.to_jsonable``) is ``data``: the inverse of that, by the
  dataclasses' fields. Fields ``data`` lacks (added to the code after it was written) keep
  ``base``'s values (see ``missing_fields``); an unknown one is a ValueError naming it."""
  if not isinstance(data, Mapping):
    raise ValueError(f"expected a JSON object of {type(base).__name__}, got {data!r}")
  return override(base, flatten(data))


def leaf_paths(config, prefix: str = "") -> list[str]:
  """The dotted path of every leaf field of a config dataclass, by its type hints."""
  hints = typing.get_type_hints(type(config))
  out = []
  for f in dataclasses.fields(config):
    value = getattr(config, f.name)
    if dataclasses.is_dataclass(hints.get(f.name)) or dataclasses.is_dataclass(value):
      out.extend(leaf_paths(value, prefix + f.name + "."))
    else:
      out.append(prefix + f.name)
  return out


def missing_fields(data: Mapping[str, Any], config) -> list[str]:
  """The leaf fields of ``config`` that the JSON ``data`` of one does not hold."""
  have = set(flatten(data))
  return [p for p in leaf_paths(config) if p not in have]


def get(config, path: str):
  for part in path.split("."):
    config = getattr(config, part)
  return config


def differences(a, b) -> list[str]:
  """The dotted leaf fields in which two configs of one class differ."""
  return [p for p in leaf_paths(a) if get(a, p) != get(b, p)]
