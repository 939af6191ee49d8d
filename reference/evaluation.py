"""The batched evaluation (``--eval batched``): the code's ``hiro.evaluate`` with its 50
episodes stepped side by side.

The code's ``evaluate`` runs 50 episodes one after another, one torch call of each actor per
env step. This one draws exactly what the code draws, in the same order (per episode: the
fresh env's reset, then ``torch.randn(3)`` for the first goal), keeps each reset state as its
own ``MjData`` of the env's model, and then steps all unfinished episodes together: both
target actors are called once per step on the batch, each episode's ``MjData`` gets the
action as ``ctrl`` and ``mj_step`` frame-skip times, as ``MujocoEnv.do_simulation`` does.

Each layer is computed as ``baddbmm`` over a batch of one-row matrices, which on this CPU's
MKL gives the same bits as the code's one-row ``nn.Linear`` (a plain batched matmul does
not: its results differ in the last bits). So the batched evaluation makes the same actions,
the same trajectories and the same success judgements as the code's. Before each use it
checks that equality on random inputs with the current weights and falls back to the code's
``evaluate`` if it fails (another CPU or thread count may pick other kernels).
``compare`` runs both from the same generator states and reports each episode.
"""

import mujoco
import numpy as np
import torch

FRAME_SKIP = 5  # AntEnv's frame skip (mujoco_env.MujocoEnv.__init__(self, file_path, 5))


def _linear(layer, x):
  """``layer(x)`` for each row of x, as the code computes it for one row (see the module)."""
  n = x.shape[0]
  out = torch.baddbmm(layer.bias.expand(n, 1, -1), x[:, None, :],
                      layer.weight.t().expand(n, -1, -1))
  return out[:, 0]


def _mlp(sequential, x):
  for module in sequential:
    x = _linear(module, x) if isinstance(module, torch.nn.Linear) else module(x)
  return x


def low_actions(actor, obs, goal):
  """ActorLow on a batch: fc(cat(state, goal)) * max_action."""
  return _mlp(actor.fc, torch.cat([obs, goal], 1)) * actor.max_action


def high_goals(actor, obs):
  """ActorHigh on a batch: fc(state) * max_goal."""
  return _mlp(actor.fc, obs) * actor.max_goal


def same_as_code(actor_l, actor_h, n=50):
  """Whether the batched actors give the code's one-row results bit for bit here."""
  gen = torch.Generator().manual_seed(12345)
  obs, goal = torch.randn(n, 30, generator=gen), torch.randn(n, 3, generator=gen)
  with torch.no_grad():
    rows_l = torch.cat([actor_l(obs[i], goal[i]) for i in range(n)])
    rows_h = torch.cat([actor_h(obs[i]) for i in range(n)])
    return (torch.equal(low_actions(actor_l, obs, goal), rows_l)
            and torch.equal(high_goals(actor_h, obs), rows_h))


def _obs(data, steps):
  """The maze env's observation: qpos[:15], qvel[:14], t * 0.001 (AntPush, no sensors)."""
  return np.concatenate([data.qpos.flat[:15], data.qvel.flat[:14], [steps * 0.001]])


def _starts(env, policy_params, goal_dim, episodes):
  """The code's per-episode draws in its order: reset states (as MjData) and first goals."""
  sim = env.wrapped_env.sim
  datas, obs, goals = [], [], []
  for i in range(10):
    env.seed(policy_params.seed + i)  # gym's no-op, as in the code
    for _ in range(5):
      if len(datas) == episodes:
        return datas, obs, goals
      obs.append(np.asarray(env.reset()))
      goals.append(torch.Tensor(torch.randn(goal_dim)))
      data = mujoco.MjData(sim.model.ptr)
      mujoco.mj_copyData(data, sim.model.ptr, sim.data.ptr)
      datas.append(data)
  return datas, obs, goals


def _step(model, data, action):
  """MujocoEnv.do_simulation through the mujoco_py stand-in's warning check."""
  import mujoco_py
  data.ctrl[:] = action
  for _ in range(FRAME_SKIP):
    mujoco.mj_step(model, data)
    mujoco_py.raise_warnings(data)


def run_batched(env, actor_l, actor_h, params, target_pos, episodes=50):
  """The code's evaluate with its episodes batched: (success count, final xyz per episode)."""
  policy_params, goal_dim = params.policy_params, params.goal_dim
  datas, first_obs, goals = _starts(env, policy_params, goal_dim, episodes)
  model = env.wrapped_env.sim.model.ptr
  obs = torch.Tensor(np.stack(first_obs))
  goal = torch.stack(goals)
  final = [o[:3].astype(np.float64) for o in first_obs]
  active = list(range(len(datas)))
  success = [False] * len(datas)
  target = target_pos.cpu()
  for steps in range(1, policy_params.episode_len + 1):
    with torch.no_grad():
      actions = low_actions(actor_l, obs, goal).numpy()
    raw = []
    for row, e in enumerate(active):
      _step(model, datas[e], actions[row])
      raw.append(_obs(datas[e], steps))
    obs = torch.Tensor(np.stack(raw))
    sq = torch.pow(obs[:, :goal_dim] - target, 2)
    done = torch.pow(sq[:, 0] + sq[:, 1] + sq[:, 2], 1 / 2) <= 5.  # success_judge's sum
    with torch.no_grad():
      goal = high_goals(actor_h, obs)
    keep = []
    for row, e in enumerate(active):
      final[e] = np.array(raw[row][:3], dtype=np.float64)
      if bool(done[row]):
        success[e] = True
      else:
        keep.append(row)
    active = [active[row] for row in keep]
    if not active:
      break
    obs, goal = obs[keep], goal[keep]
  return sum(success), final


def batched_evaluate(hiro, harness):
  """A drop-in for ``hiro.evaluate`` (same arguments, same return value: successes / 50)."""
  code_evaluate = hiro.evaluate

  def evaluate(actor_l, actor_h, params, target_pos, device):
    if not same_as_code(actor_l, actor_h):
      print("batched evaluation: the batched actors differ from the code's here; "
            "using the code's evaluate", flush=True)
      return code_evaluate(actor_l, actor_h, params, target_pos, device)
    recording, harness.recording = harness.recording, None  # the env is not stepped
    env = hiro.get_env(params.env_name)
    successes, final = run_batched(env, actor_l, actor_h, params, target_pos,
                                   harness.config.eval_episodes)
    if recording is not None:
      recording.extend(final)
    harness.recording = recording
    return successes / 50
  return evaluate
