"""The paper's methods as configurations of one agent, with presets per task.

    config = methods.make_config("ours", "AntPush")        # SPEC's numbers for that task
    config = methods.make_config("ref-ppo", "PointPush", warmup_steps=5_000)   # + overrides

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

Task presets: the Ant tasks are SPEC's (alpha, S_O, rho, 1000-step episodes, 3.15M / 6M steps).
The point tasks are the same methods at a CPU scale: 64-64 networks with faster actors, a
2K-step warm-up, a 10K-step starting mode, 100-step episodes and evaluation every 2K steps.
"""

from __future__ import annotations

import dataclasses

from nonmono_jax import homeostasis, ppo, td3
from nonmono_jax.config import AgentConfig, TopConfig

REF_PPO_EVERY = 40  # env steps between Ref:PPO's PPO updates in the paper's code (ours: 30)
METHODS = ("ours", "hiro", "ref-uniform", "ref-ppo", "ours-no-reward-mod", "ours-no-loss-mod",
           "ours-no-mods")


@dataclasses.dataclass(frozen=True)
class TaskPreset:
  """What a task fixes: its env, length of training and the paper's per-task numbers."""

  env: str
  total_steps: int
  episode_length: int
  alpha: tuple[float, float, float]
  s_o: tuple[float, float, float]
  rho: dict  # method -> homeostasis target rate
  agent: dict  # AgentConfig overrides (scale of the robot)


_ANT = {}
_POINT_TD3 = td3.TD3Config(hidden=(64, 64), lr_actor=1e-3, buffer_size=50_000)
_POINT_PPO = ppo.PPOConfig(hidden=(64, 64), std_decay_every=20_000)
_POINT = {
    "goal_range": (4.0, 4.0, 0.0), "warmup_steps": 2_000, "eval_every": 2_000,
    "eval_episodes": 20,
    "low": dataclasses.replace(_POINT_TD3, expl_noise=0.2),
    "middle": dataclasses.replace(_POINT_TD3, buffer_size=10_000),
    "middle_ppo": _POINT_PPO,
    "top": {"starting_steps": 10_000, "ppo": dataclasses.replace(_POINT_PPO, discrete=True)},
}
_PUSH = dict(alpha=(0.0, 0.4, 0.7), s_o=(0.6, 0.6, 0.6),
             rho={"ref-ppo": 0.01, "ref-uniform": 0.0001})
_FALL = dict(alpha=(-0.2, -0.2, 0.7), s_o=(0.6, 0.6, 0.9),
             rho={"ref-ppo": 0.001, "ref-uniform": 0.001})

TASKS = {
    "AntPush": TaskPreset("AntPush", 3_150_000, 1000, agent=_ANT, **_PUSH),
    "AntFall": TaskPreset("AntFall", 6_000_000, 1000, agent=_ANT, **_FALL),
    # Not in the paper: HIRO's sanity check, with Push's numbers.
    "AntMaze": TaskPreset("AntMaze", 3_150_000, 1000, agent=_ANT, **_PUSH),
    "PointPush": TaskPreset("PointPush", 100_000, 100, agent=_POINT, **_PUSH),
    "PointFall": TaskPreset("PointFall", 100_000, 100, agent=_POINT, **_FALL),
    "PointMaze": TaskPreset("PointMaze", 40_000, 100, agent=_POINT, **_PUSH),
}


def _method_fields(method: str, task: TaskPreset) -> dict:
  ours = {"switch": "top", "middle_goal_noise": 0.0}
  if method == "hiro":
    return {"switch": "none", "middle_goal_noise": 1.0, "smoothing": True}
  if method in ("ref-uniform", "ref-ppo"):
    return {"switch": "homeostasis", "middle_goal_noise": 0.0,
            "explore_mode": "random" if method == "ref-uniform" else "ppo",
            "rho": task.rho[method], **({"ref_ppo": True} if method == "ref-ppo" else {})}
  mods = {"ours": (True, True), "ours-no-reward-mod": (False, True),
          "ours-no-loss-mod": (True, False), "ours-no-mods": (False, False)}[method]
  return {**ours, "reward_mod": mods[0], "loss_mod": mods[1]}


def make_config(method: str, task: str, **overrides) -> AgentConfig:
  """The AgentConfig of ``method`` on ``task``; ``overrides`` replace AgentConfig fields."""
  if method not in METHODS:
    raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
  if task not in TASKS:
    raise ValueError(f"task must be one of {', '.join(TASKS)}; got {task!r}")
  preset = TASKS[task]
  fields = dict(preset.agent)
  top_fields = dict(fields.pop("top", {}))
  m = _method_fields(method, preset)
  top_fields.update(alpha=preset.alpha, s_o=preset.s_o,
                    reward_mod=m.pop("reward_mod", True), loss_mod=m.pop("loss_mod", True))
  middle = fields.get("middle", td3.TD3Config())
  fields["middle"] = dataclasses.replace(middle, target_smoothing=m.pop("smoothing", False))
  rho = m.pop("rho", None)
  if rho is not None:
    fields["homeostasis"] = homeostasis.HomeostasisConfig(rho=rho)
  if m.pop("ref_ppo", False):  # the paper's Ref:PPO: std 0.6 (decay commented out), every 40
    fields["middle_ppo"] = dataclasses.replace(fields.get("middle_ppo", ppo.PPOConfig()),
                                               std_decay=0.0)
    fields["middle_ppo_every"] = REF_PPO_EVERY
  fields.update(m)
  fields["top"] = TopConfig(**top_fields)
  unknown = set(overrides) - {f.name for f in dataclasses.fields(AgentConfig)}
  if unknown:
    raise ValueError(f"unknown AgentConfig field(s) {sorted(unknown)}; valid: "
                     f"{', '.join(f.name for f in dataclasses.fields(AgentConfig))}")
  fields.update(overrides)
  return AgentConfig(**fields)


PRESETS = ("paper", "quick")


def size_buffers(config: AgentConfig, steps: int) -> AgentConfig:
  """Replay buffers that hold a whole run of ``steps`` vector steps: nothing is evicted.

  The paper's buffers are append-only, sized for the run (6M Low transitions, 600K Middle):
  the Low stores one transition per env step, the Middle one per c env steps.
  """
  env_steps = steps * config.num_envs
  return dataclasses.replace(
      config, low=dataclasses.replace(config.low, buffer_size=max(env_steps, 1)),
      middle=dataclasses.replace(config.middle,
                                 buffer_size=max(-(-steps // config.c) * config.num_envs, 1)))


@dataclasses.dataclass(frozen=True)
class RunSpec:
  """How long and how wide a run is, besides the agent's configuration."""

  steps: int  # vector steps (env steps = steps x num_envs)
  seeds: int
  episode_length: int
  chunk: int  # vector steps per jitted call: one metrics row per seed each
  checkpoint_every: int  # vector steps between checkpoints (a multiple of chunk)


# quick: a 2-core CPU runs a few methods of a point task in about 10 minutes; on the ant it
# shows the whole pipeline (warm-up, starting mode, all modes live, evaluations) in minutes,
# not learning.
_QUICK_POINT = dict(steps=40_000, seeds=4, chunk=2_000, checkpoint_every=10_000)
_QUICK_ANT_AGENT = {"warmup_steps": 1_000, "eval_every": 2_000, "eval_episodes": 2,
                    "top": {"starting_steps": 1_000}}


def make_preset(preset: str, method: str, task: str) -> tuple[AgentConfig, RunSpec]:
  """The agent config and run size of ``preset`` ("paper" or "quick") for method x task."""
  if preset not in PRESETS:
    raise ValueError(f"preset must be one of {', '.join(PRESETS)}; got {preset!r}")
  config = make_config(method, task)
  t = TASKS[task]
  point = task.startswith("Point")
  if preset == "paper":
    chunk = config.eval_every
    every = chunk if point else 100_000
    return size_buffers(config, t.total_steps), RunSpec(
        steps=t.total_steps, seeds=5, episode_length=t.episode_length, chunk=chunk,
        checkpoint_every=every)
  if point:
    spec = RunSpec(episode_length=t.episode_length, **_QUICK_POINT)
    return size_buffers(config, spec.steps), spec
  top = dataclasses.replace(config.top, **_QUICK_ANT_AGENT["top"])
  config = dataclasses.replace(config, top=top, **{k: v for k, v in _QUICK_ANT_AGENT.items()
                                                   if k != "top"})
  return size_buffers(config, 6_000), RunSpec(steps=6_000, seeds=1,
                                              episode_length=t.episode_length, chunk=1_000,
                                              checkpoint_every=2_000)


def widen(config: AgentConfig, spec: RunSpec, envs_per_seed: int,
          grad_steps: int | None = None) -> tuple[AgentConfig, RunSpec]:
  """``envs_per_seed`` envs per seed at the same schedule and data use per *env* step.

  The paper runs one env per seed. To fill a GPU, a seed can run E envs, but ``num_envs``
  alone keeps every schedule in vector steps and one gradient step per vector step
  (README, "Several envs per seed"). This keeps the paper's numbers per env step instead:

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

  def batch(cfg):
    return dataclasses.replace(cfg, batch_size=-(-cfg.batch_size * E // U))

  top = dataclasses.replace(
      config.top, starting_steps=vec(config.top.starting_steps),
      ppo=dataclasses.replace(config.top.ppo, std_decay_every=vec(config.top.ppo.std_decay_every)))
  config = dataclasses.replace(
      config, num_envs=E, low_updates=U, middle_updates=U, low=batch(config.low),
      middle=batch(config.middle), warmup_steps=vec(config.warmup_steps),
      eval_every=vec(config.eval_every), top=top,
      middle_ppo=dataclasses.replace(config.middle_ppo,
                                     std_decay_every=vec(config.middle_ppo.std_decay_every)))
  chunk = vec(spec.chunk)
  steps = -(-vec(spec.steps) // chunk) * chunk
  every = max(chunk, vec(spec.checkpoint_every) // chunk * chunk)
  return size_buffers(config, steps), dataclasses.replace(spec, steps=steps, chunk=chunk,
                                                          checkpoint_every=every)
