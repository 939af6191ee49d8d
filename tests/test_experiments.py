"""The runnable modules: a tiny training run through ``experiments.train``."""

import json

import pytest

from experiments import train as train_cli


def test_train_module_runs_and_reports(tmp_path, capsys):
  out = tmp_path / "last.json"
  rc = train_cli.main(["--task", "PointMaze", "--method", "ref-ppo", "--seeds", "2",
                       "--steps", "400", "--chunk", "200", "--json", str(out)])
  assert rc == 0
  lines = capsys.readouterr().out.strip().splitlines()
  assert len(lines) == 2 and "S_E" in lines[-1]
  row = json.loads(out.read_text())
  assert row["env_steps"] == 400 and len(row["s_e"]) == 2
  assert sum(row["mode_steps"].values()) == 0  # still in the 2K-step warm-up


def test_train_module_rejects_unknown_method(capsys):
  with pytest.raises(SystemExit) as err:
    train_cli.main(["--method", "sac"])
  assert err.value.code == 2
  assert "invalid choice" in capsys.readouterr().err
