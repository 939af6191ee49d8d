"""A rollout of a trained policy as a GIF, drawn headless: ``python -m experiments.render DIR``.

Loads the run's latest checkpoint of ``--method`` (default: the run's first), runs one episode
of the evaluation policy (Middle TD3 + Low TD3 without noise; each goal held for c steps, or
with ``eval_goal="requery"``, the Ant presets', a new goal after every step as in the paper's
code) for
``--seed`` (a number, or ``best`` / ``worst``: the seed with the highest / lowest S_E at the
latest evaluation the checkpoint covers), and draws it from above: walls, chasm, the movable
blocks where they are, the target with its success radius, the robot's path, and the Middle's
current goal (the world point s[:3] + g that the Low is sent to) with the line from the robot
to it; a key below the maze names each mark (``KEY``).

    python -m experiments.render runs/quick --method hiro --seed 1 --out hiro.gif
    python -m experiments.render runs/push --method ours --seed best    # DIR/ours_seed<N>.gif

A folder needs its checkpoints (``checkpoints/``): the committed results hold rows and configs
only. A run folder of the paper's code (``reference.run``, with its ``final.pt`` or
``checkpoint.pt``; the reference venv reads it) rolls the code's target actors in our Ant Push
env with the run's engine settings (``reference.cross_eval``, which finds our evaluation and
the code's alike on such actors): ``DIR/the-code_seed<N>.gif``.

Both robots are drawn the same way (torso xy for the ant), with matplotlib: no OpenGL needed.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import jax
import jax.numpy as jp
import numpy as np

from experiments import curves
from nonmono_jax.core import evaluate
from nonmono_jax.host import checkpoints, programs as programs_lib
from reference import cross_eval


def _saved_policy(run_dir: str, method: str | None, seed: int):
  """(config, agent, Low params, Middle params, what the roll says of its run) of a run
  folder of ours: the policies S_E evaluates, the target actors by default, as the paper's
  code's."""
  plan, method, _ = programs_lib.saved_method(run_dir, method)
  if not 0 <= seed < plan.spec.seeds:
    raise ValueError(f"seed must be in [0, {plan.spec.seeds}), got {seed}")
  plan, method, step, trainer, states = programs_lib.restored(run_dir, method, plan=plan)
  config = plan.configs[method]
  pick = lambda tree: evaluate.acting_params(jax.tree.map(lambda x: x[seed], tree),
                                             config.eval_target_networks)
  info = {"task": plan.task, "method": method, "seed": seed, "step": step,
          "num_envs": config.num_envs, "warnings": plan.warnings}
  return config, trainer.agent, pick(states.low.params), pick(states.middle.params), info


def _code_policy(run_dir: str):
  """The same for a run folder of the paper's code (``reference.run``): its target actors
  (final.pt, else checkpoint.pt, read in the reference venv) in our Ant Push agent, with its
  engine settings (``reference.cross_eval``)."""
  import tempfile

  with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "actors.npz")
    if cross_eval.code_actors_npz(run_dir, path):
      raise ValueError(f"could not read the code's weights in {run_dir} (the reference venv: "
                       "python -m reference.setup)")
    data = dict(np.load(path))
  meta = json.loads(str(data["meta"]))
  k = meta["seeds"][0]
  config, agent, low, middle = cross_eval.our_policy(data, k, meta["contacts"])
  info = {"task": "AntPush", "method": "the-code", "seed": k, "step": meta["t"],
          "num_envs": 1, "warnings": []}
  return config, agent, low, middle, info


def rollout(run_dir: str, method: str | None = None, seed: int = 0, key: int = 0) -> dict:
  """One evaluation episode of a saved run: positions, goals, blocks, success per step. A
  run folder of the paper's code (``reference.run``) rolls its actors in our env."""
  if cross_eval.is_code_run(run_dir):
    config, agent, low_params, middle_params, info = _code_policy(run_dir)
  else:
    config, agent, low_params, middle_params, info = _saved_policy(run_dir, method, seed)
  env = agent.env
  goal_act = lambda params, obs, k: agent.middle.policy(params, obs)
  run_episode = evaluate.make_episode(env, config.c, agent.low.td3.act, goal_act,
                                      config.eval_goal)

  @jax.jit
  def episode(k):
    s0, records = run_episode(low_params, middle_params, k)
    first = {"pos": s0.obs[:3], "goal": records["goal"][0], "success": s0.metrics["success"],
             "blocks": env.block_positions(s0)}
    return {name: jp.concatenate([first[name][None], records[name]]) for name in first}

  out = jax.tree.map(np.asarray, episode(jax.random.PRNGKey(key)))
  return {**out, "env": env, **info}


def ranked_seed(run_dir: str, method: str | None, which: str) -> tuple[int, float, int]:
  """(seed, S_E, env step): the ``best`` or ``worst`` trained seed of ``method`` by its S_E at
  the latest evaluation the latest checkpoint covers. A tie goes to the seed with the higher
  (best) or lower (worst) mean S_E over all its evaluations up to there, then to the lower
  index."""
  plan, method, step = programs_lib.saved_method(run_dir, method)
  covered = step * plan.configs[method].num_envs
  rows = [r for r in curves.load([run_dir])
          if r["method"] == method and int(r["env_step"]) <= covered]
  scores = {}  # seed -> (S_E at its latest evaluation, mean S_E, that step)
  for k in sorted({int(r["seed"]) for r in rows}):
    steps, values = curves.per_seed([r for r in rows if int(r["seed"]) == k], plan.task,
                                      method, "eval_success")
    if len(steps):
      scores[k] = (float(values[0, -1]), float(values[0].mean()), int(steps[-1]))
  if not scores:
    raise ValueError(f"no evaluation of {method} up to its checkpoint ({covered} env steps)")
  if which == "best":
    seed = max(scores, key=lambda k: (scores[k][0], scores[k][1], -k))
  else:
    seed = min(scores, key=lambda k: (scores[k][0], scores[k][1], k))
  return seed, scores[seed][0], scores[seed][2]


def draw(roll: dict, path: str, max_frames: int = 150, fps: int = 15) -> int:
  """Writes the GIF; returns the number of frames."""
  import matplotlib
  matplotlib.use("Agg")
  import matplotlib.pyplot as plt
  from matplotlib import animation, patches

  env = roll["env"]
  lay = env.layout
  fig, ax = plt.subplots(figsize=(5, 5.8))
  walls, ghosts = lay.wall_boxes(optimised=False)
  for box in walls + ghosts:
    lo, hi = box.lo, box.hi
    ax.add_patch(patches.Rectangle(lo[:2], *(hi - lo)[:2], color="0.55", lw=0))
  s = lay.scaling
  for i, j in lay.chasm_cells():
    x, y = lay.cell_center(i, j)
    ax.add_patch(patches.Rectangle((x - s / 2, y - s / 2), s, s, color="0.1", lw=0))
  halves = [b.box.half for b in lay.blocks()]
  block_patches = [ax.add_patch(patches.Rectangle((0, 0), 2 * h[0], 2 * h[1], color="tab:brown",
                                                  alpha=0.8, lw=0)) for h in halves]
  tx, ty = float(env.target[0]), float(env.target[1])
  ax.add_patch(patches.Circle((tx, ty), float(env.success_radius), color="gold", alpha=0.3))
  ax.plot([tx], [ty], marker="*", color="goldenrod", ms=14, ls="")
  path_line, = ax.plot([], [], color="tab:blue", lw=1.5)
  robot, = ax.plot([], [], marker="o", color="tab:blue", ms=9, ls="")
  goal, = ax.plot([], [], marker="x", color="tab:red", ms=10, mew=2.5, ls="")
  link, = ax.plot([], [], color="tab:red", lw=1, ls="--")
  rows, cols = lay.shape
  x0, y0 = lay.cell_center(0, 0)
  x1, y1 = lay.cell_center(rows - 1, cols - 1)
  ax.set(xlim=(x0 - s / 2, x1 + s / 2), ylim=(y1 + s / 2, y0 - s / 2), aspect="equal",
         xticks=[], yticks=[])
  title = ax.set_title("")
  key(ax)
  pos, goals, blocks, success = roll["pos"], roll["goal"], roll["blocks"], roll["success"]
  frames = np.unique(np.linspace(0, len(pos) - 1, min(max_frames, len(pos))).astype(int))

  def update(t):
    path_line.set_data(pos[:t + 1, 0], pos[:t + 1, 1])
    robot.set_data([pos[t, 0]], [pos[t, 1]])
    goal.set_data([goals[t, 0]], [goals[t, 1]])
    link.set_data([pos[t, 0], goals[t, 0]], [pos[t, 1], goals[t, 1]])
    for p, b, h in zip(block_patches, blocks[t], halves):
      p.set_xy((b[0] - h[0], b[1] - h[1]))
    reached = bool(success[:t + 1].max())
    title.set_text(f"{roll['task']} {roll['method']} seed {roll['seed']} "
                   f"(trained {roll['step'] * roll['num_envs']} steps)\n"
                   f"step {t}{'  reached the target' if reached else ''}")
    return [path_line, robot, goal, link, title, *block_patches]

  fig.tight_layout()
  anim = animation.FuncAnimation(fig, update, frames=frames, blit=False)
  anim.save(path, writer=animation.PillowWriter(fps=fps))
  plt.close(fig)
  return len(frames)


# What each mark of the GIF is: (label, matplotlib line or patch style), in ``key``'s order.
KEY = (
    ("robot", {"marker": "o", "color": "tab:blue", "ms": 7, "ls": ""}),
    ("its path", {"color": "tab:blue", "lw": 1.5}),
    ("Middle's goal", {"marker": "x", "color": "tab:red", "ms": 8, "mew": 2.5, "ls": "--",
                       "lw": 1}),
    ("target, its radius", {"marker": "*", "color": "goldenrod", "ms": 11, "ls": ""}),
    ("block", {"patch": "tab:brown"}),
    ("chasm", {"patch": "0.1"}),
    ("wall", {"patch": "0.55"}),
)


def key(ax) -> list[str]:
  """The GIF's key below the maze (``KEY``): the robot, its path, the Middle's current goal
  (the dashed line joins it to the robot), the target with its success radius, the blocks,
  chasm and walls. Returns the labels."""
  from matplotlib import lines, patches
  handles = []
  for name, style in KEY:
    style = dict(style)
    color = style.pop("patch", None)
    handles.append(patches.Patch(color=color, label=name) if color is not None
                   else lines.Line2D([], [], label=name, **style))
  ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=4,
            fontsize=7, frameon=False, handlelength=1.6, columnspacing=1.0)
  return [h.get_label() for h in handles]


def main(argv=None) -> int:
  checkpoints.quiet_storage_leftovers()
  p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
  p.add_argument("dir", help="a run folder of ours, or of the paper's code (reference.run)")
  p.add_argument("--method", default=None, help="default: the run's first method")
  p.add_argument("--seed", default="0",
                 help="which trained seed: a number, or best / worst by S_E at the checkpoint")
  p.add_argument("--key", type=int, default=0, help="PRNG key of the episode's reset")
  p.add_argument("--out", default=None, help="GIF path (default: DIR/<method>_seed<N>.gif)")
  p.add_argument("--max-frames", type=int, default=150)
  args = p.parse_args(argv)
  if args.max_frames < 1:
    p.exit(2, f"{p.prog}: error: --max-frames must be >= 1, got {args.max_frames}\n")
  if args.out is not None:
    if os.path.isdir(args.out) or not args.out.lower().endswith(".gif"):
      p.exit(2, f"{p.prog}: error: cannot write {args.out}: --out must be a .gif file path\n")
    if not os.path.isdir(os.path.dirname(os.path.abspath(args.out))):
      p.exit(2, f"{p.prog}: error: cannot write {args.out}: its folder does not exist\n")
  if args.seed not in ("best", "worst") and not args.seed.isdigit():
    p.exit(2, f"{p.prog}: error: --seed must be a number, best or worst, got {args.seed!r}\n")
  try:
    seed = int(args.seed) if args.seed.isdigit() else None
    if seed is None and cross_eval.is_code_run(args.dir):
      raise ValueError("a run folder of the paper's code holds one seed: --seed best / worst "
                       "rank the seeds of a run of ours")
    if seed is None:
      seed, score, at = ranked_seed(args.dir, args.method, args.seed)
      print(f"{args.seed} seed: {seed} (S_E {score:.2f} at {at} env steps)")
    roll = rollout(args.dir, args.method, seed, args.key)
  except (ValueError, OSError, checkpoints.CheckpointError) as e:
    p.exit(2, f"{p.prog}: error: {e}\n")
  for warning in roll["warnings"]:
    print(f"warning: {warning}", file=sys.stderr)
  out = args.out or os.path.join(args.dir, f"{roll['method']}_seed{roll['seed']}.gif")
  try:
    n = draw(roll, out, args.max_frames)
  except OSError as e:
    p.exit(2, f"{p.prog}: error: cannot write {out}: {e.strerror or e}\n")
  print(f"{out}: {n} frames, target reached: {bool(roll['success'].max())}")
  return 0


if __name__ == "__main__":
  sys.exit(main())
