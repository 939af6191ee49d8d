"""The optional loggers beside metrics.csv and metrics.jsonl: Weights & Biases (offline here) and
TensorBoard share one set of scalars; a missing package is one line before anything runs."""

import json
import os
import sys
import types

import numpy as np
import pytest

from experiments import cli
from nonmono_jax.host import rows as rows_lib, run, sinks
from tests_support import TINY_OVERRIDES, TINY_RUN, TINY_SIZE


def _result(method, env_step, s_e):
  rows = [{**{c: "" for c in rows_lib.COLUMNS}, "task": "PointMaze", "method": method, "seed": k,
           "env_step": env_step, "eval_success": v, "train_reward": -1.0}
          for k, v in enumerate(s_e)]
  return types.SimpleNamespace(method=method, env_step=env_step, step=env_step, rows=rows,
                               metrics={"low/critic_loss": np.array([1.0, 3.0]),
                                        "horizon/p": np.array([[0.2, 0.8], [0.4, 0.6]])})


def test_scalars_are_seed_means_and_each_seeds_success():
  got = sinks.scalars(_result("ours", 200, [0.0, 1.0]))
  assert got["eval_success"] == 0.5 and got["train_reward"] == -1.0
  assert got["low/critic_loss"] == 2.0 and got["horizon/p/1"] == pytest.approx(0.7)
  assert got["eval_success/seed1"] == 1.0


def test_wandb_offline_one_run_per_method_resumed_with_its_id(tmp_path, monkeypatch):
  pytest.importorskip("wandb")
  monkeypatch.setenv("WANDB_MODE", "offline")
  monkeypatch.setenv("WANDB_SILENT", "true")
  plan = run.new_run("PointMaze", ["ours", "hiro"], preset="quick", out=str(tmp_path / "r"),
                     run=TINY_SIZE, overrides=TINY_OVERRIDES)
  os.makedirs(plan.out)
  sink = sinks.WandB(plan, "nonmono-test")
  with sinks.closing([sink]):
    for method in ("ours", "hiro"):
      sink.begin(method, 0)
      sink.write(_result(method, 200, [0.0, 1.0]))
    assert sink.runs["ours"].config["agent"]["switch"] == "top"
    assert sink.runs["hiro"].config["agent"]["switch"] == "none"
  ids = json.load(open(os.path.join(plan.out, "wandb", "ids.json")))
  assert sorted(ids) == ["hiro", "ours"] and ids["ours"] != ids["hiro"]
  offline = os.listdir(os.path.join(plan.out, "wandb"))
  assert sum(n.startswith("offline-run-") for n in offline) == 2, offline
  again = sinks.WandB(plan, "nonmono-test")  # a resumed run: the same W&B run
  with sinks.closing([again]):
    again.begin("ours", 200)
    assert again.runs["ours"].id == ids["ours"]
    again.write(_result("ours", 400, [1.0, 1.0]))


def test_a_missing_logger_package_is_one_line_before_the_run(tmp_path, monkeypatch, capsys):
  for module, flag in (("wandb", "--wandb"), ("tensorboardX", "--tensorboard")):
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    with pytest.raises(SystemExit) as e:
      cli.main("PointMaze", TINY_RUN + [flag, "--out", str(tmp_path / module)])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"python -m experiments.pointmaze: error: {flag} needs the {module} "
                   f"package: pip install 'nonmono-jax[{flag[2:]}]'"], err
    assert not os.path.exists(tmp_path / module)
