"""The device campaign: stages across time-limited commands, what comes back, and collecting it.

Run here on the CPU with the point robot: the same subprocesses, time limits, resumes and
packing as on the GPU machine, at a size that takes seconds.
"""

import csv
import json
import os

import pytest

from benchmarks.device import campaign
from tests_support import CACHE_DIR, ROOT, TINY_RUN


def _plan(tmp_path):
  payload = {"name": "tiny", "stages": [
      {"id": "pointmaze-hiro", "kind": "experiment", "task": "PointMaze",
       "argv": [*TINY_RUN, "--method", "hiro"], "results": "results/pointmaze"},
      {"id": "train-throughput", "kind": "benchmark", "estimate_s": 1,
       "argv": ["benchmarks.train_throughput", "--envs", "PointMaze", "--methods", "hiro",
                "--seeds", "1", "--num-envs", "2", "--grad-steps", "1", "--chunk", "4",
                "--repeats", "1"]},
  ]}
  path = tmp_path / "plan.json"
  path.write_text(json.dumps(payload))
  return campaign.Plan.load(str(path))


@pytest.fixture(autouse=True)
def _cache(monkeypatch):
  monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", CACHE_DIR)


def test_a_plan_runs_across_commands_and_collects_into_the_repo(tmp_path, monkeypatch):
  plan = _plan(tmp_path)
  work, repo = str(tmp_path / "work"), tmp_path / "repo"
  # Command 1 has no time left: the experiment writes its config, stops (exit 3) before its
  # first chunk, and the campaign stops there.
  monkeypatch.setattr(campaign, "MIN_STAGE_S", -1e9)
  state = campaign.run_plan(plan, work, budget=0.4, reserve=0.0)  # --time-limit 0
  assert state["pointmaze-hiro"]["status"] == "running"
  from experiments import cli

  assert state["pointmaze-hiro"]["exit"] == campaign.EXIT_TIME_LIMIT == cli.EXIT_TIME_LIMIT
  assert state["train-throughput"]["status"] == "todo"
  out1 = tmp_path / "out1"
  campaign.export(plan, work, str(out1), state)
  assert os.listdir(out1) == [campaign.EXPORT]
  campaign.collect(plan, str(out1), repo=str(repo), figures=False)
  assert (repo / "results/pointmaze/pointmaze-hiro/config.json").exists()

  # Command 2: the experiment resumes on the same machine and finishes, then the benchmark.
  monkeypatch.setattr(campaign, "MIN_STAGE_S", 30.0)
  state = campaign.run_plan(plan, work, budget=900.0)
  assert [state[s.id]["status"] for s in plan.stages] == ["done", "done"], state
  assert state["pointmaze-hiro"]["commands"] == 2
  out2 = tmp_path / "out2"
  (path,) = campaign.export(plan, work, str(out2), state)
  assert os.path.getsize(path) < 1 << 20  # metrics and logs, never checkpoints
  campaign.collect(plan, str(out2), repo=str(repo))

  run = repo / "results/pointmaze/pointmaze-hiro"
  with open(run / "metrics.csv", newline="") as f:
    rows = list(csv.DictReader(f))
  assert [int(r["env_step"]) for r in rows] == [200, 200, 400, 400, 600, 600, 800, 800]
  assert "--resume" in (run / "log.txt").read_text()
  assert (repo / "results/pointmaze/figures/pointmaze_success.png").exists()
  (bench,) = (repo / "benchmarks/results").glob("train_throughput_*.json")
  result = json.loads(bench.read_text())
  assert result["complete"] and result["results"][0]["envs_per_seed"] == 2
  assert result["results"][0]["low_batch"] == 200 and result["results"][0]["memory"]["total"] > 0
  saved = json.loads((repo / "benchmarks/device/state/tiny.json").read_text())
  assert saved == state

  # A new session (no work folder) skips what is done.
  state = campaign.load_state(plan, str(tmp_path / "fresh"), repo=str(repo))
  assert [state[s.id]["status"] for s in plan.stages] == ["done", "done"]


def test_an_unfinished_experiment_of_a_lost_machine_starts_over(tmp_path):
  plan = _plan(tmp_path)
  campaign._write_json(campaign.state_path(plan, str(tmp_path)), {"pointmaze-hiro": {
      "status": "running", "device_s": 500.0, "commands": 1, "exit": 3}})
  state = campaign.load_state(plan, str(tmp_path / "new-machine"), repo=str(tmp_path))
  assert state["pointmaze-hiro"]["status"] == "todo"
  assert state["pointmaze-hiro"]["restarts"] == 1
  assert state["train-throughput"]["status"] == "todo"


def test_what_comes_back_keeps_to_the_device_limits(tmp_path, monkeypatch):
  monkeypatch.setattr(campaign, "MAX_FILE_BYTES", 1000)
  data = os.urandom(3500)
  paths = campaign.write_parts(data, str(tmp_path / "a"))
  assert [os.path.basename(p) for p in paths] == [
      f"{campaign.EXPORT}.part0{i}" for i in range(4)]
  assert all(os.path.getsize(p) <= 1000 for p in paths)
  assert campaign.read_parts(str(tmp_path / "a")) == data
  with pytest.raises(ValueError, match="over the 8 a command can give back"):
    campaign.write_parts(os.urandom(9000), str(tmp_path / "b"))


@pytest.mark.parametrize("stage,message", [
    ({"id": "a b", "kind": "benchmark", "argv": ["m"]}, "stage id must be"),
    ({"id": "x", "kind": "train", "argv": ["m"]}, "kind must be one of"),
    ({"id": "x", "kind": "experiment", "argv": []}, "needs 'task' and 'results'"),
    ({"id": "x", "kind": "benchmark", "argv": []}, "needs 'argv'"),
])
def test_bad_stages_are_refused_naming_the_field(tmp_path, stage, message):
  path = tmp_path / "plan.json"
  path.write_text(json.dumps({"name": "bad", "stages": [stage]}))
  with pytest.raises(ValueError, match=message):
    campaign.Plan.load(str(path))


def test_the_committed_plans_are_valid_commands():
  from experiments import cli

  plans = sorted(os.listdir(os.path.join(ROOT, "benchmarks/device/plans")))
  assert plans
  for name in plans:
    plan = campaign.Plan.load(os.path.join(ROOT, "benchmarks/device/plans", name))
    for stage in plan.stages:
      if stage.kind == "experiment":  # parses and validates, as the run would
        args = cli.make_parser(stage.task).parse_args(list(stage.argv))
        run = cli.plan_from_args(stage.task, args)
        assert run.spec.steps * run.configs[args.method[0]].num_envs >= {
            "AntPush": 3_150_000, "AntFall": 6_000_000}[stage.task]
      else:
        assert stage.argv[0].startswith("benchmarks.") and stage.estimate_s > 0
