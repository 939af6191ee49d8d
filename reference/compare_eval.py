"""Run the code's ``hiro.evaluate`` and the batched one from the same start states and first
goals, on the same weights, and compare each episode.

    python -m reference.compare_eval [--checkpoint RUN/checkpoint.pt] [--episodes 50]
        [--episode-len 1000] [--perturb 2] [--target X Y Z ...]

Weights: the target actors of a checkpoint, or a fresh random init (``torch.manual_seed(0)``);
``--perturb K`` adds K copies with Gaussian noise (std 0.05) on every weight. For each weight
set and target, both evaluations start from the same torch generator state and the same env
seed, so they draw the same 50 reset states and ``randn(3)`` first goals. The default
targets are the task's (0, 19, 0.5) and two about 5.3 from the start, so that near the
success radius some episodes succeed and some do not. Prints one line per
episode (success, final distance, both ways), the times, and a JSON summary; exits 1 if any
success judgement differs.
"""

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

import reference


def parse(argv):
  p = argparse.ArgumentParser(prog="python -m reference.compare_eval", description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
  p.add_argument("--checkpoint", default="")
  p.add_argument("--episodes", type=int, default=50)
  p.add_argument("--episode-len", type=int, default=1000)
  p.add_argument("--perturb", type=int, default=0)
  p.add_argument("--target", type=float, nargs=3, action="append")
  p.add_argument("--threads", type=int, default=1)
  p.add_argument("--venv", default=os.environ.get("REFERENCE_VENV"))
  p.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
  return p.parse_args(argv)


def _weight_sets(args, hiro, params):
  import copy
  import torch
  if args.checkpoint:
    local = torch.load(args.checkpoint, weights_only=False)["locals"]
    base = [("checkpoint", local["actor_target_l"], local["actor_target_h"])]
  else:
    torch.manual_seed(0)
    pp = params.policy_params
    base = [("init", hiro.ActorLow(params.state_dim, params.goal_dim, params.action_dim,
                                   pp.max_action),
             hiro.ActorHigh(params.state_dim, params.goal_dim, pp.max_goal, "cpu"))]
  gen = torch.Generator().manual_seed(1)
  sets = list(base)
  for k in range(args.perturb):
    name, low, high = base[0]
    low, high = copy.deepcopy(low), copy.deepcopy(high)
    with torch.no_grad():
      for p in list(low.parameters()) + list(high.parameters()):
        p.add_(0.05 * torch.randn(p.shape, generator=gen))
    sets.append((f"{name}+noise{k + 1}", low, high))
  return sets


def _one(harness, hiro, params, low, high, target):
  """Both evaluations from the same generator state and env seed."""
  import torch
  from reference import evaluation
  rng, made = torch.get_rng_state(), harness.envs_made
  recorded = []
  harness.recording = recorded
  from reference.harness import _limited_range
  hiro.range = _limited_range(harness.config.eval_episodes)
  start = time.time()
  try:
    code_rate = harness.code_evaluate(low, high, params, target, "cpu")
  finally:
    code_s = time.time() - start
    harness.recording = None
    del hiro.range
  torch.set_rng_state(rng)
  harness.envs_made = made
  env = hiro.get_env(params.env_name)
  start = time.time()
  successes, final = evaluation.run_batched(env, low, high, params, target,
                                            harness.config.eval_episodes)
  batched_s = time.time() - start
  t = target.numpy().astype(float)
  dist = lambda xs: [float(((x - t) ** 2).sum() ** 0.5) for x in xs]
  return {"code_rate": code_rate, "batched_rate": successes / 50, "code_s": code_s,
          "batched_s": batched_s, "code_dist": dist(recorded), "batched_dist": dist(final),
          "bitwise": evaluation.same_as_code(low, high)}


def inside(args):
  import torch
  from reference.harness import Config, Harness
  harness = Harness(Config(out=tempfile.mkdtemp(), eval_episodes=args.episodes,
                           episode_len=args.episode_len, threads=args.threads))
  harness.install()
  hiro = harness.hiro
  params, _ = harness.code_run.load_params(1)
  targets = args.target or [[0, 19, 0.5], [0, 5.3, 0.5], [3.75, 3.75, 0.5]]
  summary, differ = [], 0
  for name, low, high in _weight_sets(args, hiro, params):
    for target in targets:
      r = _one(harness, hiro, params, low, high, torch.Tensor(target))
      judged = [(a <= 5, b <= 5) for a, b in zip(r["code_dist"], r["batched_dist"])]
      bad = sum(a != b for a, b in judged)
      gap = max(abs(a - b) for a, b in zip(r["code_dist"], r["batched_dist"]))
      differ += bad + (r["code_rate"] != r["batched_rate"])
      for i, (a, b) in enumerate(zip(r["code_dist"], r["batched_dist"])):
        print(f"{name} target={target} episode {i}: code {a <= 5} {a:.6f} batched "
              f"{b <= 5} {b:.6f}")
      summary.append({"weights": name, "target": target, "bitwise_actors": r["bitwise"],
                      "success_rate": [r["code_rate"], r["batched_rate"]],
                      "judgements_differing": bad, "max_final_distance_gap": gap,
                      "seconds": [round(r["code_s"], 2), round(r["batched_s"], 2)]})
      print(json.dumps(summary[-1]), flush=True)
  return 1 if differ else 0


def main(argv=None):
  argv = sys.argv[1:] if argv is None else argv
  args = parse(argv)
  if args.inside:
    return inside(args)
  venv = pathlib.Path(args.venv) if args.venv else reference.default_venv()
  python = str(venv / "bin" / "python")
  env = dict(os.environ, PYTHONPATH=str(reference.PACKAGE.parent))
  if args.checkpoint:
    i = argv.index("--checkpoint") if "--checkpoint" in argv else None
    if i is not None:
      argv = argv[:i + 1] + [str(pathlib.Path(argv[i + 1]).resolve())] + argv[i + 2:]
  os.execve(python, [python, "-m", "reference.compare_eval", "--inside", *argv], env)


if __name__ == "__main__":
  sys.exit(main())
