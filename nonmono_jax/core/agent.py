"""One env step of the whole agent for one seed: the paper's Algorithm 1 (vmap seeds, scan time).

A seed runs ``num_envs`` envs (1 in the paper) that share its learners and buffers. Per step t,
in the phases of ``step``:

    act:      a = clip(pi_L(s, g) + noise) (uniform in warm-up) -> env.step -> s', R, success
              Low buffer <- (s, g, a, r_L, s', g');  g <- g' = s[:3] + g - s'[:3]
              Top horizon: R_m += R, Done_m += success, Count_m += 1       (modes/)
    reset:    episode end (every episode_length steps, all envs at once)
    segment end, every c steps (a Middle decision):
              Middle TD3 buffer + Middle PPO rollout <- (s_0, g, 0.1 sum R, s_c, success)
              the mode switch: g_expl_mode from the chooser (modes/): fixed TD3 (HIRO), the
                Top PPO per Top horizon (ours), the informed trigger (Ref:*)
              next goal from the sub-policy of g_expl_mode (TD3 / PPO / RANDOM)
    updates (after warm-up): Low TD3 every step, Middle TD3 every c, Middle PPO every 30,
              the chooser's learner (Top PPO every 400)
    evaluation of Middle TD3 + Low TD3 every 10K steps -> S_E

The numbers a variant may change (the config fields declared ``traced``: alpha, S_O, the Top's
two switches, rho, the goal noise, the learners' rates; ``lanes.py``) are read from ``hp``,
the lane's ``Numbers``: ``step(state, t, hp)``, ``hp = lanes.of(config)``. Every gate is a
function of the global step ``t``, which is not batched over seeds, so each stays a real
``lax.cond`` under ``vmap`` (docs/spec.md, section 6); only per-env data (modes, explore
periods) is batched. Metrics are ``metrics.Metric``s that declare their chunk reduction.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jp
from flax import struct

from envs.base import MazeEnv, MazeState
from nonmono_jax.core import buffers, hierarchy, modes, td3
from nonmono_jax.core import evaluate as evaluate_lib
from nonmono_jax.core.config import AgentConfig
from nonmono_jax.core.gates import gated
from nonmono_jax.core.lanes import Numbers
from nonmono_jax.core.low import Low, make_low
from nonmono_jax.core.metrics import Metric, level
from nonmono_jax.core.middle import Middle, MiddlePPOState, NoMiddlePPOState, Segment, make_middle

N_MODES = len(hierarchy.MODES)


@struct.dataclass
class SeedState:
  """Everything one seed owns; per-env fields have a leading ``num_envs`` axis."""

  env: MazeState  # (E,)
  low: td3.TD3State
  middle: td3.TD3State
  middle_ppo: MiddlePPOState | NoMiddlePPOState  # the Middle PPO and its rollout (E, ...)
  chooser: modes.ChooserState  # the chooser's own (modes/: Fixed, TopState, TriggerState), (E,)
  low_buffer: buffers.ReplayBuffer
  middle_buffer: buffers.ReplayBuffer
  goal: jax.Array  # (E, 3)
  segment: Segment  # (E,)
  mode: jax.Array  # (E,) int32 g_expl_mode in effect
  mode_steps: jax.Array  # (3,) int32 env steps run in each mode after warm-up
  mode_decisions: jax.Array  # (3,) int32 Middle decisions in each mode after warm-up
  mode_steps_after_start: jax.Array  # (3,) the same after the starting mode
  mode_decisions_after_start: jax.Array  # (3,)
  s_e: jax.Array  # the latest evaluation success rate S_E
  eval_distance: jax.Array  # and its mean final distance to the target
  eval_return: jax.Array  # and its mean episode return
  key: jax.Array
  # Fields added later go last, so that older checkpoints restore by leaf position
  # (host/checkpoints.py).
  segment_start: jax.Array  # (E, obs) the Middle TD3's s_0 of the current segment (middle.py)
  eval_by_kind: jax.Array  # (3,) the latest S_E of each evaluation kind (evaluate.KINDS)

  def filled(self, saved_leaves: int) -> "SeedState":
    """This state restored from a checkpoint that held only its first ``saved_leaves``
    leaves (written before the last fields were added), the missing fields set as the code
    of that checkpoint behaved: ``segment_start`` is the segment's first state, the latest
    S_E per kind 0 (none yet). Works on one seed's state or the lanes' (leading axes)."""
    n, changes = 0, {}
    for field in dataclasses.fields(self):
      if n >= saved_leaves and field.name == "segment_start":
        changes["segment_start"] = self.segment.obs[..., 0, :]
      elif n >= saved_leaves and field.name == "eval_by_kind":
        changes["eval_by_kind"] = jp.zeros_like(self.eval_by_kind)
      n += len(jax.tree.leaves(getattr(self, field.name)))
    return self.replace(**changes)

  def learner_params(self) -> dict:
    """The parameters of every learner the seed has, by level name (for NaN checks)."""
    return {"low": self.low.params, "middle": self.middle.params,
            **self.middle_ppo.learner_params(), **self.chooser.learner_params()}


class _NamedKeys:
  """Keys by name: ``split(key)`` gives one key per field, in field order."""

  @classmethod
  def split(cls, key):
    return cls(*jax.random.split(key, len(dataclasses.fields(cls))))


@struct.dataclass
class InitKeys(_NamedKeys):
  env: jax.Array
  low: jax.Array
  middle: jax.Array
  middle_ppo: jax.Array
  top: jax.Array
  horizon: jax.Array
  goals: jax.Array
  next: jax.Array


@struct.dataclass
class StepKeys(_NamedKeys):
  """One step's keys by phase. ``unused_1`` / ``unused_2`` keep the split's layout (and so
  every random stream of earlier runs); the PPO updates take no key."""

  next: jax.Array
  act: jax.Array
  reset: jax.Array
  switch: jax.Array
  horizon: jax.Array
  goals: jax.Array
  low: jax.Array
  middle: jax.Array
  unused_1: jax.Array
  unused_2: jax.Array
  eval: jax.Array
  relabel: jax.Array


@struct.dataclass
class Clock:
  """The schedule at global step t (unbatched: every flag below gates a real branch)."""

  t: jax.Array
  warm: jax.Array  # in warm-up: random actions and goals, no learning
  live: jax.Array  # after warm-up
  i: jax.Array  # the step's index within its segment
  episode_end: jax.Array
  segment_end: jax.Array


@struct.dataclass
class EnvStep:
  """One env's data of one step: the per-env pytree that the ``vmap``s map over."""

  s: jax.Array
  goal: jax.Array
  action: jax.Array
  s_next: jax.Array
  reward: jax.Array
  success: jax.Array


@dataclasses.dataclass(frozen=True, eq=False)  # identity: its levels hold arrays
class Agent:
  """The agent (``make_agent`` builds it): its levels, the chooser and the evaluation, and its
  pure functions ``init(key) -> SeedState``, ``step(state, t, hp) -> (state, metrics)`` and
  ``evaluate(state, t, key) -> Evaluation``, composed of the phases below."""

  config: AgentConfig
  env: MazeEnv
  low: Low
  middle: Middle
  chooser: modes.ModeChooser
  evaluator: evaluate_lib.Evaluator

  def init(self, key) -> SeedState:
    return _init(self, key)

  def step(self, state: SeedState, t, hp: Numbers) -> tuple[SeedState, dict]:
    return _step(self, state, t, hp)

  def evaluate(self, state: SeedState, t, key) -> evaluate_lib.Evaluation:
    return _evaluate(self, state, t, key)


def _per_env(fn, shared, per_env):
  """``fn(shared, one_env)`` for every env: ``shared`` unbatched, ``per_env`` a pytree (E, ...)."""
  return jax.vmap(fn, in_axes=(None, 0))(shared, per_env)


def _count(state, live, after_start, field, field_after_start):
  """Add one to each env's current mode in ``field`` (and after the starting mode)."""
  n = jax.nn.one_hot(state.mode, N_MODES, dtype=jp.int32).sum(0)
  return state.replace(**{field: getattr(state, field) + n * live,
                          field_after_start: getattr(state, field_after_start)
                          + n * after_start}), n * live


def _counts(prefix, counted):
  return {f"{prefix}/{name}": Metric.sum(counted[j]) for j, name in enumerate(hierarchy.MODES)}


def _new_segments(p: Agent, state, obs, key, warm, t, noise):
  """The goals of new segments from ``obs`` in each env's mode (random where ``warm``)."""
  shared = {"td3": state.middle.params, "ppo": p.middle.ppo.params(state.middle_ppo),
            "noise": noise}
  per_env = {"obs": obs, "mode": state.mode, "key": jax.random.split(key, p.config.num_envs)}
  goal, ppo_action, log_prob = _per_env(
      lambda sh, e: p.middle.goal(sh["td3"], sh["ppo"], e["obs"], e["mode"], e["key"], warm, t,
                                  sh["noise"]),
      shared, per_env)
  return state.replace(goal=goal, segment_start=obs, segment=jax.vmap(p.middle.new_segment)(
      obs, goal, ppo_action, log_prob))


def _init(p: Agent, key) -> SeedState:
  """A seed's state: fresh learners and buffers, reset envs, the first modes and goals."""
  keys, E = InitKeys.split(key), p.config.num_envs
  zeros_modes = jp.zeros((N_MODES,), jp.int32)
  env_state = jax.vmap(p.env.reset)(jax.random.split(keys.env, E))
  middle = p.middle.td3.init(keys.middle)
  chooser, mode = p.chooser.init(keys, env_state.obs, middle.params)
  state = SeedState(
      env=env_state, low=p.low.td3.init(keys.low), middle=middle,
      middle_ppo=p.middle.init_ppo(keys.middle_ppo, E), chooser=chooser,
      low_buffer=p.low.init_buffer(), middle_buffer=p.middle.init_buffer(),
      goal=jp.zeros((E, hierarchy.GOAL_SIZE)),
      segment=jax.vmap(p.middle.new_segment)(env_state.obs, jp.zeros((E, hierarchy.GOAL_SIZE)),
                                             jp.zeros((E, hierarchy.GOAL_SIZE)), jp.zeros(E)),
      mode=mode, mode_steps=zeros_modes, mode_decisions=zeros_modes,
      mode_steps_after_start=zeros_modes, mode_decisions_after_start=zeros_modes,
      s_e=jp.zeros(()), eval_distance=jp.zeros(()), eval_return=jp.zeros(()), key=keys.next,
      segment_start=env_state.obs, eval_by_kind=jp.zeros((len(evaluate_lib.KINDS),)))
  # Random goals in warm-up: the goal noise does not matter here.
  return _new_segments(p, state, env_state.obs, keys.goals, True, 0,
                       p.config.middle_goal_noise)


def _clock(p: Agent, t) -> Clock:
  warm = t < p.config.warmup_steps
  i = t % p.config.c
  return Clock(t=t, warm=warm, live=jp.logical_not(warm), i=i,
               episode_end=(t + 1) % p.env.episode_length == 0, segment_end=i == p.config.c - 1)


def _act(p: Agent, state: SeedState, clock: Clock, keys: StepKeys, hp: Numbers):
  """Low acts in every env and the envs step; the Low buffer, segments and horizons record it."""
  s = state.env.obs
  per_env = {"s": s, "goal": state.goal, "key": jax.random.split(keys.act, p.config.num_envs)}
  a = _per_env(lambda params, e: p.low.act(params, e["s"], e["goal"], e["key"], clock.warm,
                                           hp.low), state.low.params, per_env)
  env_next = jax.vmap(p.env.step)(state.env, a)
  scored = env_next if p.config.scored_state == "next" else state.env  # the code: s
  step = EnvStep(s=s, goal=state.goal, action=a, s_next=env_next.obs, reward=scored.reward,
                 success=scored.success)
  low_tr = jax.vmap(lambda e: p.low.transition(e.s, e.goal, e.action, e.s_next))(step)
  state, counted = _count(state, clock.live, clock.t >= p.chooser.live_from, "mode_steps",
                          "mode_steps_after_start")
  segment = _per_env(lambda i, e: p.middle.record(e["segment"], i, e["step"].action,
                                                  e["step"].s_next, e["step"].reward,
                                                  e["step"].success),
                     clock.i, {"segment": state.segment, "step": step})
  state = state.replace(
      env=env_next, low_buffer=buffers.add(state.low_buffer, low_tr), goal=low_tr.next_context,
      segment=segment, chooser=p.chooser.accumulate(state.chooser, step.reward, step.success),
      key=keys.next)
  metrics = {"reward": Metric.mean(step.reward.mean()),
             "success": Metric.mean(step.success.mean()),
             "distance": Metric.mean(env_next.distance.mean()),
             "low/reward": Metric.mean(low_tr.reward.mean()),
             "physics/unstable": Metric.sum(jax.vmap(p.env.unstable)(env_next).sum()),
             **_counts("count", counted)}
  return state, metrics


def _reset(p: Agent, state: SeedState, clock: Clock, keys: StepKeys) -> SeedState:
  """Episode end. It falls on a segment's end (episode_length is a multiple of c), after s_c
  is recorded. With ``episode_start="reset"`` the reset comes before the segment's end, so the
  next goal and mode are chosen from the new state; with ``"last"`` (the paper's code) after
  it: they are chosen from the episode's last state, and the relative goal carries over. The
  new segment's Middle TD3 s_0 is then that last state, or with
  ``middle_td3_first_state="reset"`` (the code) the reset state."""
  td3_from_reset = p.config.middle_td3_first_state == "reset"

  def reset(written):
    env = jax.vmap(p.env.reset)(jax.random.split(keys.reset, p.config.num_envs))
    return env, env.obs if td3_from_reset else written[1]

  # Only what the reset writes goes through the cond (gates.py: a pass-through is a copy).
  env, start = jax.lax.cond(clock.episode_end, reset, lambda w: w,
                            (state.env, state.segment_start))
  return state.replace(env=env, segment_start=start)


def _subgoals(start, end) -> dict:
  """The Low's competence at a segment's end: the remaining offset to its subgoal, ||g_c||,
  whether it came within the Low's done distance (1.5), and how much closer it got,
  ||g_0|| - ||g_c|| (``start``: the goal emitted at s_0), averaged over envs and segments."""
  dist = jp.linalg.norm(end, axis=-1)
  reached = (dist <= hierarchy.LOW_DONE_DISTANCE).astype(jp.float32)
  progress = jp.linalg.norm(start, axis=-1) - dist
  return {"low/subgoal_distance": Metric.when(dist.mean(), 1.0),
          "low/subgoal_reached": Metric.when(reached.mean(), 1.0),
          "low/subgoal_progress": Metric.when(progress.mean(), 1.0)}


def _end_segment(p: Agent, state: SeedState, clock: Clock, keys: StepKeys, hp: Numbers):
  """A Middle decision: Middle transitions into the TD3 buffer and PPO rollout; the mode
  switch; the next goals."""
  t, warmup = clock.t, p.config.warmup_steps

  def end_segment(state):
    per_env = {"segment": state.segment, "start": state.segment_start,
               "key": jax.random.split(keys.relabel, p.config.num_envs)}
    items, steps = _per_env(
        lambda low_params, e: p.middle.close(e["segment"], clock.episode_end, low_params,
                                             e["key"], e["start"]), state.low.params, per_env)
    state = state.replace(middle_buffer=buffers.add(state.middle_buffer, items),
                          middle_ppo=p.middle.ppo.store(state.middle_ppo, t, steps))
    decision = modes.Decision(t=t, episode_end=clock.episode_end, obs=state.env.obs,
                              s_c=items["transition"].next_obs,
                              reward=items["transition"].reward, middle=state.middle.params)
    chooser, mode, m = p.chooser.decide(state.chooser, state.mode, decision, keys, hp)
    state, decided = _count(state.replace(chooser=chooser, mode=mode), t + 1 >= warmup,
                            t + 1 >= p.chooser.live_from, "mode_decisions",
                            "mode_decisions_after_start")
    m = {**m, **_counts("decisions", decided), **_subgoals(state.segment.goal, state.goal)}
    return _new_segments(p, state, state.env.obs, keys.goals, t + 1 < warmup, t,
                         hp.middle_goal_noise), m

  return gated(clock.segment_end, end_segment, state)  # zeros where skipped


def _updates(p: Agent, state: SeedState, clock: Clock, keys: StepKeys, hp: Numbers):
  """Learning after warm-up, each level on its own clock."""
  t, live = clock.t, clock.live

  def low_update(low, buffer):
    return p.low.update(low, buffer, keys.low, t, hp.low)

  def middle_update(middle, buffer, low_params):
    return p.middle.td3_update(middle, buffer, low_params, keys.middle, t, hp.middle)

  def middle_ppo_update(middle_ppo):
    return p.middle.ppo.update(middle_ppo, t, hp.middle_ppo)

  low, m_low = gated(live, low_update, state.low, (state.low_buffer,))
  middle, m_middle = gated(live & clock.segment_end, middle_update, state.middle,
                           (state.middle_buffer, low.params))
  state = state.replace(low=low, middle=middle)
  metrics = {**level("low", m_low, live), **level("middle", m_middle, live & clock.segment_end)}
  if p.middle.ppo.trains:
    every = p.config.middle_ppo_every
    ran = live & (t % every == every - 1)
    middle_ppo, m = gated(ran, middle_ppo_update, state.middle_ppo)
    state = state.replace(middle_ppo=middle_ppo)
    metrics.update(level("middle_ppo", m, ran))
  chooser, m = p.chooser.update(state.chooser, t, live, state.s_e, hp)
  return state.replace(chooser=chooser), {**metrics, **m}


def _evaluation(p: Agent, state: SeedState, clock: Clock, keys: StepKeys, hp: Numbers):
  """Middle TD3 + Low TD3 without noise every ``eval_every`` steps: S_E (evaluate.py)."""
  ran = clock.live & ((clock.t + 1) % p.config.eval_every == 0)

  def evaluation(written, state):
    ev = _evaluate(p, state, clock.t, keys.eval)
    kinds = {f"success_{k}": ev.by_kind[evaluate_lib.KINDS.index(k)]
             for k in p.evaluator.kinds}
    return ((ev.success, ev.distance, ev.return_, ev.by_kind),
            {"success": ev.success, "distance": ev.distance, "return": ev.return_,
             "unstable": ev.unstable, **kinds})

  written = (state.s_e, state.eval_distance, state.eval_return, state.eval_by_kind)
  (s_e, distance, return_, by_kind), m = gated(ran, evaluation, written, (state,))
  state = state.replace(s_e=s_e, eval_distance=distance, eval_return=return_,
                        eval_by_kind=by_kind)
  return state, level("eval", m, ran)


def _evaluate(p: Agent, state: SeedState, t, key) -> evaluate_lib.Evaluation:
  """The seed's evaluation (``evaluate.py``) at global step ``t`` (the Middle PPO's std)."""
  ppo = {"params": p.middle.ppo.params(state.middle_ppo), "t": t}
  return p.evaluator(state.low.params, state.middle.params, ppo, key)


def _step(p: Agent, state: SeedState, t, hp: Numbers):
  """One env step of every env of the seed, at global step ``t`` (unbatched), with the
  lane's numbers ``hp``."""
  keys, clock = StepKeys.split(state.key), _clock(p, t)
  state, metrics = _act(p, state, clock, keys, hp)
  reset_first = p.config.episode_start == "reset"
  if reset_first:
    state = _reset(p, state, clock, keys)
  state, m = _end_segment(p, state, clock, keys, hp)
  metrics.update(m)
  if not reset_first:
    state = _reset(p, state, clock, keys)
  for phase in (_updates, _evaluation):
    state, m = phase(p, state, clock, keys, hp)
    metrics.update(m)
  return state, metrics


def make_agent(env, config: AgentConfig = AgentConfig()) -> Agent:
  """Build the agent for an env of ``envs`` (obs[:3] is the robot's xyz): every level from
  the config, each reading its own fields."""
  config.check_env(env.episode_length)
  target = jp.asarray(env.target, jp.float32)
  low = make_low(env.observation_size, env.action_size, env.action_limit, config)
  middle = make_middle(env.observation_size, env.action_size, target, config, low.td3.act)
  chooser = modes.make_chooser(config, env.observation_size, target, middle.value)
  evaluator = evaluate_lib.make_evaluate(
      env, config.c, low.td3.act, middle.policy, config.eval_episodes,
      config.eval_target_networks, config.eval_goal, config.eval_extra,
      middle.ppo_goal if middle.ppo.trains else None)
  return Agent(config=config, env=env, low=low, middle=middle, chooser=chooser,
               evaluator=evaluator)
