"""The choices where the paper's code differs from this project's first reading, which the Ant
presets take (docs/fidelity.md): PyTorch's initialisation, the Middle PPO's std decay at
step 0, the Low's done on the current goal, training scored on the state before the step,
an episode's first goal and mode from its predecessor's last state, the Middle TD3 on the
state alone, and PPO returns that end only at their own terminals."""

import functools

import jax
import jax.numpy as jp
import numpy as np
import pytest

import envs
from nonmono_jax.core import agent as agent_lib
from nonmono_jax.core import low as low_lib
from nonmono_jax.core import hierarchy, middle as middle_lib, networks, lanes, ppo, td3
from nonmono_jax.core.modes import top as top_lib
from nonmono_jax.core.config import AgentConfig, TopConfig
from nonmono_jax.host import methods

OBS, ACT = 7, 2
SMALL = td3.TD3Config(hidden=(8,), batch_size=4, buffer_size=64)
CODE = {"low.init": "torch", "middle.init": "torch", "middle_ppo.init": "torch",
        "top.ppo.init": "torch", "middle_ppo.decay_at_start": True, "low_done_goal": "current",
        "scored_state": "current", "episode_start": "last", "middle_td3_input": "state",
        "returns_cross_episodes": True, "middle_td3_first_state": "reset",
        "warmup_goal": "gaussian", "eval_goal": "requery",
        "eval_extra": ("held", "ppo"), "low.target_noise": "batch",
        "top.ppo.value_weighting": "batch", "relabel_ties": "random"}


@pytest.mark.parametrize("method", methods.METHODS)
def test_ant_presets_take_the_codes_choices_and_point_presets_keep_ours(method):
  for task in ("AntPush", "AntFall", "AntMaze"):
    config = methods.build_config("paper", method, task)[0]
    for path, value in CODE.items():
      part = config
      for name in path.split("."):
        part = getattr(part, name)
      assert part == value, (task, path)
  point = methods.build_config("paper", method, "PointPush")[0]
  assert (point.low.init, point.low_done_goal, point.scored_state, point.episode_start,
          point.middle_td3_input, point.returns_cross_episodes,
          point.middle_ppo.decay_at_start) == ("lecun", "next", "next", "reset", "state_target",
                                               False, False)
  assert (point.middle_td3_first_state, point.warmup_goal, point.eval_goal,
          point.eval_extra) == ("last", "uniform", "held", ())
  assert (point.low.target_noise, point.top.ppo.value_weighting, point.relabel_ties) == (
      "sample", "sample", "original")


def test_torch_initialisation_is_uniform_in_one_over_sqrt_fan_in():
  """PyTorch's nn.Linear default: weights and biases U(+-1/sqrt(fan_in)); ours (lecun) has
  zero biases and sqrt(3) times the weights' scale."""
  net = networks.make_mlp(400, (300,), 200, init="torch")
  params = net.init(jax.random.PRNGKey(0))["params"]
  for name, fan_in in (("dense_0", 400), ("dense_1", 300)):
    w, b = np.asarray(params[name]["kernel"]), np.asarray(params[name]["bias"])
    bound = 1 / np.sqrt(fan_in)
    assert np.abs(w).max() <= bound and np.abs(b).max() <= bound
    assert w.std() == pytest.approx(bound / np.sqrt(3), rel=0.02)
    assert b.std() == pytest.approx(bound / np.sqrt(3), rel=0.2)
  lecun = networks.make_mlp(400, (300,), 200).init(jax.random.PRNGKey(0))["params"]["dense_0"]
  np.testing.assert_array_equal(lecun["bias"], 0.0)
  assert np.asarray(lecun["kernel"]).std() == pytest.approx(1 / np.sqrt(400), rel=0.02)
  with pytest.raises(ValueError, match="init must be one of lecun, torch"):
    td3.TD3Config(init="xavier")


def test_middle_ppo_std_decays_at_step_zero_in_the_code():
  """The code's ``t % 250000 == 0`` fires at t = 0: 0.55 on [0, 250K), 0.1 from 2.25M."""
  code = ppo.PPOConfig(decay_at_start=True)
  std = lambda t, c: float(ppo.gaussian_std(t, c))
  assert [std(t, code) for t in (0, 249_999, 250_000, 2_000_000, 2_250_000, 9_000_000)] == \
      pytest.approx([0.55, 0.55, 0.5, 0.15, 0.1, 0.1])
  assert std(0, ppo.PPOConfig()) == pytest.approx(0.6)


@pytest.mark.parametrize("done_goal", ["next", "current"])
def test_low_done_tests_the_current_goal_in_the_code(done_goal):
  low = low_lib.make_low(OBS, ACT, 1.0, AgentConfig(low=SMALL, low_done_goal=done_goal))
  s, a = jp.zeros(OBS), jp.zeros(ACT)
  near, far = jp.array([1.0, 0.0, 0.0]), jp.array([5.0, 0.0, 0.0])
  s_moved = s.at[0].set(4.5)  # from s the goal `far` is 5 away, from s' 0.5
  assert float(low.transition(s, far, a, s_moved).done) == (done_goal == "next")
  assert float(low.transition(s, near, a, s.at[0].set(-5.0)).done) == (done_goal == "current")


def test_middle_td3_sees_the_state_alone_in_the_code():
  target = jp.array([0.0, 9.5, 0.5])
  config = methods.build_config("paper", "ours", "PointPush", {
      "low": SMALL, "middle": SMALL, "middle_ppo.hidden": (8,), "middle_td3_input": "state"})[0]
  low = low_lib.make_low(OBS, ACT, 1.0, config)
  mid = middle_lib.make_middle(OBS, ACT, target, config, low.td3.act)
  params = mid.td3.init(jax.random.PRNGKey(0)).params
  assert params.actor["params"]["dense_0"]["kernel"].shape[0] == OBS  # pi_M(s)
  assert params.critic["params"]["dense_0"]["kernel"].shape[1] == OBS + 3  # Q(s, g)
  assert mid.policy(params, jp.ones(OBS)).shape == (3,)
  assert mid.value(params, jp.ones((4, OBS))).shape == (4,)
  buffer = mid.init_buffer()
  assert buffer.data["transition"].context.shape[-1] == 0
  # The Middle PPO still sees (s, target).
  ppo_params = mid.ppo.learner.init(jax.random.PRNGKey(1)).params
  assert ppo_params["actor"]["params"]["dense_0"]["kernel"].shape[0] == OBS + 3


@pytest.mark.parametrize("cross", [False, True])
def test_ppo_returns_end_at_episode_ends_unless_they_cross_them(cross):
  top_config = TopConfig(ppo=ppo.PPOConfig(hidden=(8,), discrete=True))
  top = top_lib.make_top(OBS, jp.zeros(3), AgentConfig(top=top_config,
                                                      returns_cross_episodes=cross))
  h = top.start(top.ppo.init(jax.random.PRNGKey(0)).params, jp.zeros(OBS),
                jax.random.PRNGKey(1), True)
  h = top.accumulate(h, -30.0, 0.0)  # far from the target: done_m = 0
  step, m = top.close(h, False, True, lanes.of(top_config))  # at an episode's end
  assert float(m["done_m"]) == 0.0 and float(step.done) == (0.0 if cross else 1.0)
  config = methods.build_config("paper", "ours", "PointPush", {
      "low": SMALL, "middle": SMALL, "middle_ppo.hidden": (8,), "returns_cross_episodes": cross})[0]
  low = low_lib.make_low(OBS, ACT, 1.0, config)
  mid = middle_lib.make_middle(OBS, ACT, jp.zeros(3), config, low.td3.act)
  seg = mid.new_segment(jp.zeros(OBS), jp.zeros(3), jp.zeros(3), jp.zeros(()))
  _, ppo_step = mid.close(seg, True, low.td3.init(jax.random.PRNGKey(2)).params,
                          jax.random.PRNGKey(3))
  assert float(ppo_step.done) == (0.0 if cross else 1.0)


EPISODE, C = 20, 5


@pytest.fixture(scope="module")
def code_agent():
  env = envs.make("PointPush", episode_length=EPISODE)
  small = {"hidden": (8,), "batch_size": 4, "buffer_size": 200}
  config = methods.build_config("paper", "hiro", "PointPush", {
      "c": C, "warmup_steps": 10, "eval_every": 1000, "eval_episodes": 1,
      **{f"low.{k}": v for k, v in small.items()}, **{f"middle.{k}": v for k, v in small.items()},
      "scored_state": "current", "episode_start": "last"})[0]
  agent = agent_lib.make_agent(env, config)
  return env, agent, jax.jit(functools.partial(agent.step, hp=lanes.of(config)))


def test_training_scores_the_state_before_the_step_and_keeps_the_last_goal(code_agent):
  """With the code's choices, step t's task reward and success are those of s_t (the state it
  starts from), and an episode's first goal is chosen at the last state of the one before."""
  env, agent, step = code_agent
  state = agent.init(jax.random.PRNGKey(0))
  for t in range(EPISODE):
    before = state
    state, m = step(state, t)
    np.testing.assert_allclose(m["reward"].value, before.env.reward.mean(), rtol=1e-6)
    np.testing.assert_allclose(m["success"].value, before.env.success.mean())
  # t = EPISODE - 1 ended the episode: the envs were reset after the Middle decision, which
  # saw the episode's last state s_T (the Low's last stored s'): the new segment starts there,
  # the env at its reset state.
  s_last = np.asarray(state.low_buffer.data.next_obs[EPISODE - 1])  # one env per seed
  np.testing.assert_array_equal(np.asarray(state.env.steps), 0)
  np.testing.assert_array_equal(np.asarray(state.segment.obs[:, 0]), s_last[None])
  assert not np.allclose(np.asarray(state.env.obs)[0, :3], s_last[:3])


@pytest.fixture(scope="module")
def first_state_agent():
  """The code's choices at an episode's start, ours: the Middle PPO."""
  env = envs.make("PointPush", episode_length=EPISODE)
  small = {"hidden": (8,), "batch_size": 4, "buffer_size": 200}
  config = methods.build_config("paper", "ours", "PointPush", {
      "c": C, "warmup_steps": 10, "eval_every": 1000, "eval_episodes": 1, "top.horizon": 10,
      "middle_ppo_every": C, "top.train_every": 20, "middle_ppo.hidden": (8,),
      "top.ppo.hidden": (8,), **{f"low.{k}": v for k, v in small.items()},
      **{f"middle.{k}": v for k, v in small.items()}, "episode_start": "last",
      "middle_td3_first_state": "reset"})[0]
  agent = agent_lib.make_agent(env, config)
  return agent, jax.jit(functools.partial(agent.step, hp=lanes.of(config)))


def test_the_middle_td3_starts_an_episode_at_the_reset_state_and_the_ppo_at_the_last(
    first_state_agent):
  """The code clears the Middle TD3's state sequence at a reset: the first Middle TD3
  transition of an episode starts at the reset state (t * 0.001 = 0 in the observation's last
  entry), while the Middle PPO keeps the state where it chose (the old episode's last)."""
  agent, step = first_state_agent
  state = agent.init(jax.random.PRNGKey(0))
  for t in range(EPISODE + C):
    state, _ = step(state, t)
  s_last = np.asarray(state.low_buffer.data.next_obs[EPISODE - 1])
  first = jax.tree.map(lambda x: np.asarray(x[EPISODE // C]),
                       state.middle_buffer.data["transition"])  # the new episode's first
  assert first.obs[-1] == 0.0 and not np.allclose(first.obs, s_last)
  np.testing.assert_allclose(first.obs, np.asarray(state.low_buffer.data.obs[EPISODE]))
  slot = (EPISODE + C - 1) // C % agent.config.middle_rollout_length
  ppo_obs = np.asarray(state.middle_ppo.rollout.obs[0, slot, :OBS])
  np.testing.assert_allclose(ppo_obs, s_last)
  before = jax.tree.map(lambda x: np.asarray(x[EPISODE // C - 1]),
                        state.middle_buffer.data["transition"])  # the old episode's last
  np.testing.assert_allclose(before.next_obs, s_last)


@pytest.mark.parametrize("kind", ["uniform", "gaussian"])
def test_warmup_goals_are_clipped_gaussians_in_the_code(kind):
  """The code's warm-up goals are clip(randn * range): about 32 % of each coordinate sits on
  the range's edge; uniform goals never do. The RANDOM mode keeps ``random_goal``."""
  config = methods.build_config("paper", "ours", "PointPush", {"low": SMALL, "middle": SMALL,
                                                     "middle_ppo.hidden": (8,),
                                                     "warmup_goal": kind})[0]
  low = low_lib.make_low(OBS, ACT, 1.0, config)
  mid = middle_lib.make_middle(OBS, ACT, jp.zeros(3), config, low.td3.act)
  td3_params = mid.td3.init(jax.random.PRNGKey(0)).params
  ppo_params = mid.ppo.learner.init(jax.random.PRNGKey(1)).params
  goals = jax.vmap(lambda k, warm: mid.goal(td3_params, ppo_params, jp.zeros(OBS),
                                            hierarchy.RANDOM, k, warm, 0, 0.0)[0],
                   in_axes=(0, None))
  keys = jax.random.split(jax.random.PRNGKey(2), 4000)
  warm, random = np.asarray(goals(keys, True)), np.asarray(goals(keys, False))
  edge = lambda g: np.mean(np.isclose(np.abs(g[:, :2]), 4.0))
  assert edge(random) == 0.0  # random_goal stays uniform
  assert np.abs(warm[:, :2]).max() <= 4.0
  if kind == "gaussian":
    assert edge(warm) == pytest.approx(0.3173, abs=0.02)
  else:
    assert edge(warm) == 0.0
