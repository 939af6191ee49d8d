"""The agent step of every method: invariants over a short vmapped run (Algorithm 1's schedule).

One small program per switch kind (HIRO, ours, Ref:Uniform, Ref:PPO), each compiled once per
session; the ablations differ from ours only in the Top's reward and loss (``test_top.py``).
"""

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs
from nonmono_jax.core import agent as agent_lib
from nonmono_jax.core import hierarchy, homeostasis, lanes, ppo, summary, td3, train
from nonmono_jax.core import config as config_lib
from nonmono_jax.core.config import AgentConfig, TopConfig
from nonmono_jax.core.modes.top import TopState
from nonmono_jax.core.modes.trigger import TriggerState
from nonmono_jax.host import methods

C, HORIZON, TOP_EVERY, MID_PPO_EVERY = 5, 25, 50, 15
WARMUP, STARTING, STEPS, EPISODE = 100, 100, 500, 100
ENVS, SEEDS = 2, 3
EXPLORE = 20

_small = td3.TD3Config(hidden=(16, 16), batch_size=8, buffer_size=2000)
_ppo = ppo.PPOConfig(hidden=(16, 16))


SMALL = {
    "c": C, "warmup_steps": WARMUP, "middle_ppo_every": MID_PPO_EVERY, "eval_every": 100,
    "eval_episodes": 2, "num_envs": ENVS, "top.horizon": HORIZON, "top.train_every": TOP_EVERY,
    "top.starting_steps": STARTING, "top.ppo": _ppo, "top.ppo.discrete": True,
    "homeostasis.rho": 0.05, "homeostasis.explore_steps": EXPLORE, "homeostasis.k": C,
    "low": _small, "middle_ppo": _ppo}


def small_config(method: str, overrides=None) -> AgentConfig:
  """The method's PointPush config at a test's size; the Middle keeps the method's smoothing."""
  smoothing = methods.build_config("paper", method, "PointPush")[0].middle.target_smoothing
  return methods.build_config("paper", method, "PointPush", config_lib.merge(
      SMALL, {"middle": _small, "middle.target_smoothing": smoothing}, overrides or {}))[0]


class Run:
  """A method's short run: states at 0 / end of warm-up / end, and per-step records."""

  def __init__(self, method):
    self.env = envs.make("PointPush", episode_length=EPISODE)
    self.config = small_config(method)
    self.agent = agent_lib.make_agent(self.env, self.config)
    ag, hp = self.agent, lanes.of(self.config)

    def body(st, t):
      mode = st.mode
      trigger = isinstance(st.chooser, TriggerState)
      left = st.chooser.explore_left if trigger else jp.zeros_like(mode)
      st, m = jax.vmap(ag.step, in_axes=(0, None, None))(st, t, hp)
      return st, ({k: v.value for k, v in m.items()}, mode, left)

    @jax.jit
    def chunk(states, t0):  # one compiled program of WARMUP steps, called STEPS / WARMUP times
      return jax.lax.scan(body, states, t0 + jp.arange(WARMUP))

    def go(keys):
      start = jax.jit(jax.vmap(ag.init))(keys)
      states, records = start, []
      for t0 in range(0, STEPS, WARMUP):
        states, rec = chunk(states, t0)
        records.append(rec)
        if t0 == 0:
          mid = states
      return start, mid, states, jax.tree.map(lambda *r: jp.concatenate(r), *records)

    self.go = go
    self.keys = jax.random.split(jax.random.PRNGKey(0), SEEDS)
    self.start, self.mid, self.end, (metrics, self.modes, self.left) = go(self.keys)
    self.metrics = jax.tree.map(np.asarray, metrics)
    self.modes, self.left = np.asarray(self.modes), np.asarray(self.left)  # (T, seeds, envs)


_runs = {}


@pytest.fixture(scope="module")
def runs():
  def get(method):
    if method not in _runs:
      _runs[method] = Run(method)
    return _runs[method]
  return get


def _same(a, b):
  return all(jax.tree.leaves(jax.tree.map(lambda x, y: bool(jp.all(x == y)), a, b)))


ALL = ("hiro", "ours", "ref-uniform", "ref-ppo")


@pytest.mark.parametrize("method", ALL)
def test_mode_counts_add_up_to_steps_after_warmup(runs, method):
  r = runs(method)
  np.testing.assert_array_equal(r.end.mode_steps.sum(-1), (STEPS - WARMUP) * ENVS)
  for j, name in enumerate(hierarchy.MODES):  # the per-step counts are the modes in effect
    np.testing.assert_array_equal(r.metrics[f"count/{name}"][WARMUP:].sum(0),
                                  r.end.mode_steps[:, j])
    np.testing.assert_array_equal(r.metrics[f"count/{name}"][WARMUP:],
                                  (r.modes[WARMUP:] == j).sum(-1))


@pytest.mark.parametrize("method", ALL)
def test_the_rows_summary_reads_what_the_step_reports(runs, method):
  """core/summary.py looks every metric up by the name the step gives it: a renamed one fails
  here (KeyError), not as an empty column of a run's metrics.csv."""
  r = runs(method)
  # the run records values: their mean over the run stands in for each metric's reduction
  reduced = {k: v.mean(0) for k, v in r.metrics.items()}
  s = jax.tree.map(np.asarray, summary.summarise(r.end, reduced))
  np.testing.assert_array_equal(s.cum_steps, r.end.mode_steps)
  assert (s.updates.low > 0).all() and (s.updates.middle > 0).all()
  assert np.isfinite(s.losses.low_critic).all() and np.isfinite(s.losses.middle_actor).all()
  assert set(s.params_finite) == set(r.end.learner_params())
  assert all(ok.all() for ok in [*s.params_finite.values(), *s.metrics_finite.values()])


@pytest.mark.parametrize("method", ALL)
def test_buffers_and_update_clocks(runs, method):
  r = runs(method)
  np.testing.assert_array_equal(r.end.low_buffer.size, STEPS * ENVS)
  np.testing.assert_array_equal(r.end.middle_buffer.size, STEPS // C * ENVS)
  assert _same(r.start.low.params, r.mid.low.params)  # nothing learns in warm-up
  assert _same(r.start.middle.params, r.mid.middle.params)
  assert not _same(r.mid.low.params.critic, r.end.low.params.critic)
  assert not _same(r.mid.middle.params.actor, r.end.middle.params.actor)
  live = STEPS - WARMUP
  ticks = lambda every: sum(t % every == every - 1 for t in range(WARMUP, STEPS))
  m = r.metrics
  assert np.all(m["low/updated"][:WARMUP] == 0) and np.all(m["low/updated"][WARMUP:] == 1)
  assert np.all(m["low/critic_loss"][WARMUP:] > 0)
  np.testing.assert_array_equal(m["middle/updated"].sum(0), ticks(C))
  np.testing.assert_array_equal(m["eval/updated"].sum(0), live // 100)
  np.testing.assert_array_equal(r.end.s_e, m["eval/success"][-1])
  if r.config.uses_middle_ppo:
    np.testing.assert_array_equal(m["middle_ppo/updated"].sum(0), ticks(MID_PPO_EVERY))
    assert not _same(r.mid.middle_ppo.learner.params, r.end.middle_ppo.learner.params)
  else:
    assert jax.tree.leaves(r.end.middle_ppo) == [] and "middle_ppo/updated" not in m
  if r.config.switch == "top":
    np.testing.assert_array_equal(m["top/updated"].sum(0), ticks(TOP_EVERY))
    np.testing.assert_array_equal(m["horizon/updated"].sum(0), STEPS // HORIZON)
    assert not _same(r.mid.chooser.learner.params, r.end.chooser.learner.params)
  else:
    assert not isinstance(r.end.chooser, TopState) and "top/updated" not in m


def test_hiro_never_leaves_td3(runs):
  r = runs("hiro")
  assert np.all(r.modes == hierarchy.TD3)
  assert r.config.middle_goal_noise == 1.0 and r.config.middle.target_smoothing


def test_ours_starts_in_random_then_the_top_chooses(runs):
  r = runs("ours")
  assert r.config.middle_goal_noise == 0.0 and not r.config.middle.target_smoothing
  assert np.all(r.modes[:WARMUP + STARTING] == hierarchy.RANDOM)
  later = r.modes[WARMUP + STARTING:]
  assert set(np.unique(later)) == {0, 1, 2}
  # The mode changes only at Top horizon boundaries.
  changed = np.any(r.modes[1:] != r.modes[:-1], axis=(1, 2))
  assert np.all(np.nonzero(changed)[0] % HORIZON == HORIZON - 1)
  # Top transitions: the rollout holds the latest horizons, in time order, with their modes.
  last = r.modes[STEPS - TOP_EVERY::HORIZON]  # (rollout, seeds, envs)
  np.testing.assert_array_equal(np.moveaxis(np.asarray(r.end.chooser.rollout.action), 2, 0), last)


def _explore_runs(modes, explore):
  """(start, length) of each run of ``explore`` in a (T,) mode sequence."""
  runs, start = [], None
  for t, m in enumerate(list(modes) + [-1]):
    if m == explore and start is None:
      start = t
    elif m != explore and start is not None:
      runs.append((start, t - start))
      start = None
  return runs


@pytest.mark.parametrize("method,explore", [("ref-uniform", hierarchy.RANDOM),
                                            ("ref-ppo", hierarchy.PPO)])
def test_ref_starting_phase_then_only_the_trigger(runs, method, explore):
  """The paper's Ref code: explore through warm-up + the starting mode, then exploit; after
  that only the trigger starts explore periods, at Middle decisions, each exactly
  ``explore_steps`` long, and only once the exploit period holds k segments."""
  r = runs(method)
  live_from, k = WARMUP + STARTING, r.config.homeostasis.k
  assert set(np.unique(r.modes)) == {hierarchy.TD3, explore}
  assert np.all(r.modes[:live_from] == explore) and np.all(r.modes[live_from] == hierarchy.TD3)
  switches = r.metrics["switch/switches"]
  assert switches[:live_from].sum() == 0
  n_runs = 0
  for seed in range(SEEDS):
    for e in range(ENVS):
      exploit_from = live_from
      for start, length in _explore_runs(r.modes[:, seed, e], explore)[1:]:
        assert start % C == 0 and start - exploit_from >= k * C, (start, exploit_from)
        assert length == EXPLORE or start + length == STEPS, length
        exploit_from = start + length
        n_runs += 1
  assert n_runs == switches.sum() > 0  # every explore period is one switch of the trigger
  episode_starts = r.modes[EPISODE::EPISODE]  # no explore period at an episode's start (X)
  assert np.mean(episode_starts == explore) < 0.5


@pytest.mark.parametrize("method", ALL)
def test_counts_in_env_steps_and_middle_decisions(runs, method):
  """Counts in the paper's unit (Middle decisions) and in env steps, after warm-up and after
  the starting mode, add up."""
  r = runs(method)
  end, live_from = r.end, WARMUP + (0 if method == "hiro" else STARTING)  # HIRO: no start
  decisions = (STEPS - WARMUP) // C + 1  # per env: at t + 1 = WARMUP, ..., STEPS
  np.testing.assert_array_equal(end.mode_decisions.sum(-1), decisions * ENVS)
  np.testing.assert_array_equal(end.mode_decisions_after_start.sum(-1),
                                ((STEPS - live_from) // C + 1) * ENVS)
  np.testing.assert_array_equal(end.mode_steps_after_start.sum(-1), (STEPS - live_from) * ENVS)
  # each decision but the last (its segment has not run) holds for c env steps
  last = np.stack([(np.asarray(end.mode) == j).sum(-1) for j in range(3)], -1)
  np.testing.assert_array_equal(end.mode_steps + C * last, C * end.mode_decisions)
  np.testing.assert_array_equal(end.mode_steps_after_start + C * last,
                                C * end.mode_decisions_after_start)
  for j, name in enumerate(hierarchy.MODES):
    np.testing.assert_array_equal(r.metrics[f"decisions/{name}"].sum(0), end.mode_decisions[:, j])


@pytest.mark.parametrize("method", ALL)
def test_seeds_differ_and_runs_repeat(runs, method):
  r = runs(method)
  w = jax.tree.leaves(r.end.low.params.actor)[0]
  assert not np.allclose(w[0], w[1])
  again = r.go(r.keys)[2]
  assert _same(r.end.low.params, again.low.params) and _same(r.end.env.obs, again.env.obs)
  assert _same(r.end.mode_steps, again.mode_steps)


def test_gates_stay_branches_under_vmap(runs):
  """Each horizon gate is a ``cond`` in the vmapped step's jaxpr, not a select of both sides."""
  r = runs("ours")
  states = jax.vmap(r.agent.init)(r.keys)
  hp = lanes.of(r.config)
  jaxpr = str(jax.make_jaxpr(jax.vmap(r.agent.step, in_axes=(0, None, None)))(
      states, jp.array(0), hp))
  # episode reset, segment end, Top horizon, Low, Middle, Middle PPO, Top PPO, evaluation, and
  # the delayed TD3 actors
  assert jaxpr.count("cond[") >= 10, jaxpr.count("cond[")
  batched = str(jax.make_jaxpr(jax.vmap(r.agent.step, in_axes=(0, 0, None)))(
      states, jp.zeros(SEEDS, jp.int32), hp))
  assert batched.count("cond[") < jaxpr.count("cond[")  # a batched clock would lose them


def test_every_method_builds_from_its_preset():
  env = envs.make("PointPush", episode_length=EPISODE)
  for method in methods.METHODS:
    config = small_config(method)
    agent_lib.make_agent(env, config)
  ours = methods.build_config("paper", "ours", "AntFall")[0]
  assert ours.top.alpha == (-0.2, -0.2, 0.7) and ours.top.s_o == (0.6, 0.6, 0.9)
  assert methods.build_config("paper", "ref-ppo", "AntPush")[0].homeostasis.rho == 0.01
  assert methods.build_config("paper", "ref-uniform", "AntPush")[0].homeostasis.rho == 0.0001
  assert methods.build_config("paper", "ref-uniform", "AntPush")[0].explore_mode == "random"
  nr = methods.build_config("paper", "ours-no-reward-mod", "AntPush")[0].top
  nl = methods.build_config("paper", "ours-no-loss-mod", "AntPush")[0].top
  nm = methods.build_config("paper", "ours-no-mods", "AntPush")[0].top
  assert (nr.reward_mod, nr.loss_mod, nl.reward_mod, nl.loss_mod) == (False, True, True, False)
  assert not nm.reward_mod and not nm.loss_mod
  push = methods.build_config("paper", "ours", "AntPush")[0]
  assert push.warmup_steps == 100_000 and push.top.starting_steps == 250_000
  assert push.c == 10 and push.top.horizon == 50 and push.low.hidden == (300, 300)


def test_bad_config_fails_before_compiling():
  with pytest.raises(ValueError, match="goal_range"):
    AgentConfig(goal_range=(1.0, 1.0))
  with pytest.raises(ValueError, match="switch must be one of"):
    AgentConfig(switch="bandit")
  with pytest.raises(ValueError, match="top.alpha"):
    TopConfig(alpha=(0.0, 0.4))
  with pytest.raises(ValueError, match="top.s_o"):
    TopConfig(s_o=(0.6, 0.6, 1.5))
  with pytest.raises(ValueError, match="top.horizon"):
    TopConfig(horizon=-50)
  with pytest.raises(ValueError, match="multiple of c"):
    AgentConfig(c=7)
  with pytest.raises(ValueError, match="rho"):
    homeostasis.HomeostasisConfig(rho=2.0)
  with pytest.raises(ValueError, match="method must be one of"):
    methods.build_config("paper", "sac", "AntPush")[0]
  with pytest.raises(ValueError, match="task must be one of"):
    methods.build_config("paper", "ours", "HalfCheetah")[0]
  with pytest.raises(ValueError, match="unknown AgentConfig field"):
    methods.build_config("paper", "ours", "AntPush", {"horizon": 3})[0]
  with pytest.raises(ValueError, match="multiple of top.horizon"):
    agent_lib.make_agent(envs.make("PointMaze", episode_length=60), AgentConfig())


def test_trainer_chunks_match_the_plain_scan(runs):
  """train.make_trainer's chunks are the same program as scanning agent.step by hand."""
  r = runs("ours")
  trainer = train.make_trainer(r.env, r.config, num_seeds=SEEDS, chunk_steps=250)
  states = jax.jit(jax.vmap(trainer.agent.init))(r.keys)  # chunk donates: distinct buffers
  states, first = trainer.chunk(states, 0)
  states, metrics = trainer.chunk(states, 250)
  assert metrics["success"].shape == (SEEDS,)
  assert set(metrics) == set(r.metrics)  # every metric of the step reaches the chunk's output
  for name in ("low/q", "middle/target_q", "middle_ppo/approx_kl", "middle_ppo/std",
               "top/clip_fraction", "top/entropy", "horizon/s_o_m", "horizon/r_final"):
    assert name in metrics, name
  # low/reward: the mean over all steps, warm-up included (not only where the Low updated)
  np.testing.assert_allclose(first["low/reward"], r.metrics["low/reward"][:250].mean(0),
                             rtol=1e-5)
  np.testing.assert_allclose(states.env.obs, r.end.env.obs, rtol=1e-5, atol=1e-5)
  np.testing.assert_array_equal(states.mode_steps, r.end.mode_steps)
  # Chunk metrics: counts summed, level metrics averaged where the level updated.
  np.testing.assert_array_equal(metrics["count/TD3"], r.metrics["count/TD3"][250:].sum(0))
  flag = r.metrics["top/updated"][250:]
  np.testing.assert_allclose(metrics["top/loss"],
                             (r.metrics["top/loss"][250:] * flag).sum(0) / flag.sum(0), rtol=1e-4)
  with pytest.raises(ValueError, match="num_seeds"):
    train.make_trainer(r.env, r.config, num_seeds=0, chunk_steps=10)


def test_the_lows_subgoal_columns():
  """At a segment's end: ||g_c||, the share within the Low's done distance 1.5, and the
  progress ||g_0|| - ||g_c||, each averaged over the seed's envs."""
  m = agent_lib._subgoals(jp.array([[3.0, 0.0, 0.0], [0.0, 4.0, 0.0]]),
                          jp.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]))
  assert {k: float(v.value) for k, v in m.items()} == {
      "low/subgoal_distance": 1.5, "low/subgoal_reached": 0.5, "low/subgoal_progress": 2.0}
