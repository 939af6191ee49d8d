"""The paper's methods and tasks as data, and the one function that turns them into a
configuration: tables of dotted overrides (``config.override``) applied to ``AgentConfig()``.

    config, spec = methods.build_config("paper", "ours", "AntPush")   # the paper's numbers
    config, spec = methods.build_config("quick", "ref-ppo", "PointPush", {"warmup_steps": 5_000},
                                        run={"steps": 20_000}, widen={"envs_per_seed": 4})

| method              | switch       | Middle sub-policies        | Top loss / reward mods |
|---------------------|--------------|----------------------------|------------------------|
| ours                | top          | TD3 (no noise), PPO, RANDOM| both                   |
| hiro                | none         | TD3 + N(0, 1) goal noise   | -                      |
| ref-uniform         | homeostasis  | TD3 / RANDOM               | -                      |
| ref-ppo             | homeostasis  | TD3 / PPO                  | -                      |
| ours-no-reward-mod  | top          | as ours                    | alpha = 0              |
| ours-no-loss-mod    | top          | as ours                    | no S_E term            |
| ours-no-mods        | top          | as ours                    | neither                |

HIRO keeps its Middle TD3 target smoothing and Gaussian goal noise; ours and the Ref methods
have neither (exploration comes from the modes). The Ref methods' TD3 goals are noiseless too
(their explore mode is the exploration).

Task presets: the Ant tasks are the paper's (docs/spec.md: alpha, S_O, rho, 1000-step episodes,
3.15M / 6M steps).
The point tasks are the same methods at a CPU scale: 64-64 networks with faster actors, a
2K-step warm-up, a 10K-step starting mode, 100-step episodes and evaluation every 2K steps.

The layers, in the order ``build_config`` merges them: the task's, the method's, its rho, the
preset's (``preset_layers``), the widening (``widen_layer``), replay buffers sized for the run
(``buffer_sizes``) and the caller's overrides. ``build_config`` is the one function that
returns an ``AgentConfig``: the command, the run library, the tests and the benchmarks all
build theirs through it. This module imports no JAX (the command's ``--help`` reads it).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from nonmono_jax.core.config import AgentConfig, get, merge, override

REF_PPO_EVERY = 40  # env steps between Ref:PPO's PPO updates in the paper's code (ours: 30)

# --- methods: what each changes in AgentConfig() ----------------------------------------------

_OURS = {"switch": "top", "middle_goal_noise": 0.0}
METHOD_OVERRIDES = {
    "ours": {**_OURS, "top.reward_mod": True, "top.loss_mod": True},
    "hiro": {"switch": "none", "middle_goal_noise": 1.0, "middle.target_smoothing": True},
    "ref-uniform": {"switch": "homeostasis", "middle_goal_noise": 0.0, "explore_mode": "random"},
    # The paper's Ref:PPO: std 0.6 (its decay commented out), PPO every 40 env steps.
    "ref-ppo": {"switch": "homeostasis", "middle_goal_noise": 0.0, "explore_mode": "ppo",
                "middle_ppo.std_decay": 0.0, "middle_ppo_every": REF_PPO_EVERY},
    "ours-no-reward-mod": {**_OURS, "top.reward_mod": False, "top.loss_mod": True},
    "ours-no-loss-mod": {**_OURS, "top.reward_mod": True, "top.loss_mod": False},
    "ours-no-mods": {**_OURS, "top.reward_mod": False, "top.loss_mod": False},
}
METHODS = tuple(METHOD_OVERRIDES)


# --- tasks: the robot's scale and the paper's per-task numbers --------------------------------

@dataclasses.dataclass(frozen=True)
class TaskPreset:
  """What a task fixes: its env, length of training and the paper's per-task numbers. The one
  registry of tasks: the experiment modules (``experiments/<task>.py``), the calibration and
  the presets read it; the env itself is ``envs.make(env)``."""

  env: str
  robot: str  # "ant" or "point": which PRESET_TABLE rows apply
  total_steps: int
  episode_length: int
  agent: dict  # dotted AgentConfig overrides: the robot's scale, alpha, S_O
  rho: dict  # method -> homeostasis target rate (the Ref methods)
  # a random policy's success rate (256 episodes; `python -m experiments.random_baseline`):
  # the calibration's floor (docs/results.md, "The study")
  random_success: float = 0.0


# The Ant presets follow the paper's code where it made a choice this project first made
# otherwise (docs/fidelity.md); the point presets keep the earlier choices, so that the
# committed point study reproduces.
_TORCH_INIT = {f"{learner}.init": "torch" for learner in ("low", "middle", "middle_ppo", "top.ppo")}
_ANT: dict = {**_TORCH_INIT, "middle_ppo.decay_at_start": True, "low_done_goal": "current",
              "scored_state": "current", "episode_start": "last", "middle_td3_input": "state",
              "returns_cross_episodes": True, "middle_td3_first_state": "reset",
              "warmup_goal": "gaussian", "eval_goal": "requery",
              "eval_extra": ("held", "ppo"), "low.target_noise": "batch",
              "top.ppo.value_weighting": "batch", "relabel_ties": "random"}
_POINT_TD3 = {"hidden": (64, 64), "lr_actor": 1e-3}
_POINT_PPO = {"hidden": (64, 64), "std_decay_every": 20_000}
_POINT = {
    "goal_range": (4.0, 4.0, 0.0), "warmup_steps": 2_000, "eval_every": 2_000,
    "eval_episodes": 20, "top.starting_steps": 10_000,
    **{f"low.{k}": v for k, v in _POINT_TD3.items()}, "low.buffer_size": 50_000,
    "low.expl_noise": 0.2,
    **{f"middle.{k}": v for k, v in _POINT_TD3.items()}, "middle.buffer_size": 10_000,
    **{f"middle_ppo.{k}": v for k, v in _POINT_PPO.items()},
    **{f"top.ppo.{k}": v for k, v in _POINT_PPO.items()},
}
_PUSH = {"top.alpha": (0.0, 0.4, 0.7), "top.s_o": (0.6, 0.6, 0.6)}
_FALL = {"top.alpha": (-0.2, -0.2, 0.7), "top.s_o": (0.6, 0.6, 0.9)}
_PUSH_RHO = {"ref-ppo": 0.01, "ref-uniform": 0.0001}
_FALL_RHO = {"ref-ppo": 0.001, "ref-uniform": 0.001}

TASKS = {
    "AntPush": TaskPreset("AntPush", "ant", 3_150_000, 1000, {**_ANT, **_PUSH}, _PUSH_RHO),
    "AntFall": TaskPreset("AntFall", "ant", 6_000_000, 1000, {**_ANT, **_FALL}, _FALL_RHO),
    # Not in the paper: HIRO's sanity check, with Push's numbers.
    "AntMaze": TaskPreset("AntMaze", "ant", 3_150_000, 1000, {**_ANT, **_PUSH}, _PUSH_RHO),
    "PointPush": TaskPreset("PointPush", "point", 100_000, 100, {**_POINT, **_PUSH}, _PUSH_RHO,
                            random_success=0.004),
    "PointFall": TaskPreset("PointFall", "point", 100_000, 100, {**_POINT, **_FALL}, _FALL_RHO),
    "PointMaze": TaskPreset("PointMaze", "point", 40_000, 100, {**_POINT, **_PUSH}, _PUSH_RHO),
}


def task_of_module(module: str) -> str:
  """The task an experiment module runs: ``experiments.antpush`` -> ``AntPush``."""
  name = module.rsplit(".", 1)[-1]
  found = [t for t in TASKS if t.lower() == name]
  if not found:
    raise ValueError(f"no task named {name!r}; tasks: {', '.join(TASKS)}")
  return found[0]


def preset_overrides(method: str, task: str) -> dict:
  """The dotted overrides of ``method`` on ``task``: the task's, the method's, its rho."""
  if method not in METHODS:
    raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
  if task not in TASKS:
    raise ValueError(f"task must be one of {', '.join(TASKS)}; got {task!r}")
  preset = TASKS[task]
  rho = {"homeostasis.rho": preset.rho[method]} if method in preset.rho else {}
  return merge(preset.agent, METHOD_OVERRIDES[method], rho)


def buffer_sizes(steps: int, c: int, num_envs: int) -> dict:
  """The dotted buffer sizes that hold a whole run of ``steps`` vector steps: nothing is
  evicted. The paper's buffers are append-only, sized for the run (6M Low transitions, 600K
  Middle): the Low stores one transition per env step, the Middle one per c env steps."""
  return {"low.buffer_size": max(steps * num_envs, 1),
          "middle.buffer_size": max(-(-steps // c) * num_envs, 1)}


@dataclasses.dataclass(frozen=True)
class RunSpec:
  """How long and how wide a run is, besides the agent's configuration."""

  steps: int  # vector steps (env steps = steps x num_envs)
  seeds: int
  episode_length: int
  chunk: int  # vector steps per jitted call: one metrics row per seed each
  checkpoint_every: int  # vector steps between checkpoints (a multiple of chunk)


# (preset, robot) -> (dotted agent overrides, run size); the paper's length is the task's.
# paper: a row per evaluation (eval_every), 5 seeds (our choice: the paper does not say how
# many it ran) and a checkpoint every 100K steps on the ant. quick: a 2-core CPU runs a few
# methods of a point task in about 10 minutes; on the ant it shows the whole pipeline (warm-up,
# starting mode, all modes live, evaluations) in minutes, not learning.
PRESET_TABLE = {
    ("paper", "point"): ({}, {"seeds": 5, "chunk": 2_000, "checkpoint_every": 2_000}),
    ("paper", "ant"): ({}, {"seeds": 5, "chunk": 10_000, "checkpoint_every": 100_000}),
    ("quick", "point"): ({}, {"steps": 40_000, "seeds": 4, "chunk": 2_000,
                              "checkpoint_every": 10_000}),
    ("quick", "ant"): ({"warmup_steps": 1_000, "eval_every": 2_000, "eval_episodes": 2,
                        "top.starting_steps": 1_000},
                       {"steps": 6_000, "seeds": 1, "chunk": 1_000, "checkpoint_every": 2_000}),
}
PRESETS = ("paper", "quick")


def preset_layers(preset: str, method: str, task: str) -> tuple[dict, RunSpec]:
  """The dotted overrides of ``preset`` ("paper" or "quick") for method x task (the task's,
  the method's, the preset's) and the preset's run size."""
  if preset not in PRESETS:
    raise ValueError(f"preset must be one of {', '.join(PRESETS)}; got {preset!r}")
  layers = preset_overrides(method, task)  # checks the method and the task
  t = TASKS[task]
  agent, run = PRESET_TABLE[preset, t.robot]
  spec = RunSpec(**{"steps": t.total_steps, "episode_length": t.episode_length, **run})
  return merge(layers, agent), spec


def widen_layer(config: AgentConfig, spec: RunSpec, envs_per_seed: int,
                grad_steps: int | None = None) -> tuple[dict, RunSpec]:
  """The dotted overrides and run size that run ``envs_per_seed`` envs per seed at the same
  schedule and data use per *env* step as ``config`` and ``spec`` with one.

  The paper runs one env per seed. To fill a GPU, a seed can run E envs, but ``num_envs``
  alone keeps every schedule in vector steps and one gradient step per vector step
  (docs/training.md, "Several envs per seed"). This keeps the paper's numbers per env step instead:

  - schedules in env steps become vector steps / E (rounded up): warm-up, the starting mode,
    evaluation, the PPO std decay, the run's length and its checkpoints;
  - gradient samples per env step stay the paper's: per vector step the Low makes
    ``grad_steps`` (U) TD3 updates of batch ``low.batch_size * E / U``, and per Middle horizon
    the Middle U updates of batch ``middle.batch_size * E / U``. U = E repeats the paper's
    update exactly; a smaller U takes fewer, larger steps (cheaper on a GPU).

  What does not change: the Middle and Top horizons (c, top.horizon) and episodes are per
  env; the PPO levels train every ``middle_ppo_every`` / ``top.train_every`` vector steps on
  the E envs' latest transitions, so they see the same data per env step in E-times larger,
  E-times fewer updates.
  """
  E = envs_per_seed
  U = E if grad_steps is None else grad_steps
  if E < 1:
    raise ValueError(f"--envs-per-seed must be >= 1, got {E}")
  if not 1 <= U <= E:
    raise ValueError(f"--grad-steps must be in [1, --envs-per-seed ({E})], got {U}")
  if config.num_envs != 1 or config.low_updates != 1 or config.middle_updates != 1:
    raise ValueError("widen applies to a preset with one env and one update per step")

  def vec(n):  # env steps -> vector steps
    return -(-n // E)

  layer = {
      "num_envs": E, "low_updates": U, "middle_updates": U,
      "low.batch_size": -(-config.low.batch_size * E // U),
      "middle.batch_size": -(-config.middle.batch_size * E // U),
      "warmup_steps": vec(config.warmup_steps), "eval_every": vec(config.eval_every),
      "top.starting_steps": vec(config.top.starting_steps),
      "top.ppo.std_decay_every": vec(config.top.ppo.std_decay_every),
      "middle_ppo.std_decay_every": vec(config.middle_ppo.std_decay_every)}
  chunk = vec(spec.chunk)
  steps = -(-vec(spec.steps) // chunk) * chunk
  every = max(chunk, vec(spec.checkpoint_every) // chunk * chunk)
  return layer, dataclasses.replace(spec, steps=steps, chunk=chunk, checkpoint_every=every)


# --- the configuration of a run ---------------------------------------------------------------

RUN_FIELDS = tuple(f.name for f in dataclasses.fields(RunSpec))


def build_config(preset: str, method: str, task: str,
                 overrides: Mapping[str, Any] | None = None, run: Mapping[str, Any] | None = None,
                 widen: Mapping[str, Any] | None = None) -> tuple[AgentConfig, RunSpec]:
  """(config, run size) of ``method`` on ``task`` under ``preset`` ("paper" or "quick"), in
  one pass. The run size first: the preset's, widened (``widen["envs_per_seed"]`` and
  ``"grad_steps"``, ``widen_layer``), then ``run``'s changes (``RUN_FIELDS``). Then the config,
  ``override`` applied once to ``AgentConfig()`` with the dotted layers merged in order: the
  preset's (task, method, preset), the widening, replay buffers sized for the run
  (``buffer_sizes``, from the merged c and num_envs), the caller's ``overrides`` (dotted
  paths, so a buffer size given there wins). Raises ValueError naming the field."""
  overrides, widen = dict(overrides or {}), dict(widen or {})
  layers, spec = preset_layers(preset, method, task)
  wide = {}
  if widen.get("envs_per_seed") is not None:
    wide, spec = widen_layer(override(AgentConfig(), layers), spec, widen["envs_per_seed"],
                             widen.get("grad_steps"))
  spec = _resized(spec, dict(run or {}))
  given = merge(layers, wide, overrides)
  value = lambda path: given.get(path, get(AgentConfig(), path))
  c, num_envs = value("c"), value("num_envs")
  valid = all(isinstance(v, int) and v >= 1 for v in (c, num_envs))  # else the config says so
  sized = buffer_sizes(spec.steps, c, num_envs) if valid else {}
  config = _explained(override, overrides, AgentConfig(), merge(layers, wide, sized, overrides))
  return config, spec


def _resized(spec: RunSpec, run: dict) -> RunSpec:
  unknown = set(run) - set(RUN_FIELDS)
  if unknown:
    raise ValueError(f"unknown run field(s) {sorted(unknown)}; valid: {', '.join(RUN_FIELDS)}")
  changes = {k: v for k, v in run.items() if v is not None}
  if "chunk" in changes and "checkpoint_every" not in changes:
    changes["checkpoint_every"] = max(changes["chunk"], spec.checkpoint_every // changes["chunk"]
                                      * changes["chunk"])
  return dataclasses.replace(spec, **changes)


def _explained(fn, flat: dict, *args):
  """``fn(*args)``; a ValueError about one field that another, user-set one caused (``--c 7``
  breaking ``middle_ppo_every``) also names the user's overrides it mentions."""
  try:
    return fn(*args)
  except ValueError as e:
    msg = str(e)
    subject = msg.split(" ")[0]
    mentioned = [n for n in flat if n != subject and (f" {n} " in msg or f" {n}:" in msg
                                                      or f"{n} (" in msg)]
    if mentioned:
      given = ", ".join(f"--{n} {_show(flat[n])}" for n in mentioned)
      msg += f" (from {given}: change {subject} too, or that flag)"
    raise ValueError(msg) from None


def _show(value) -> str:
  return " ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)
