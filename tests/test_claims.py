"""The Ant Push study's readings (experiments/claims.py) on made-up rows: each claim's three
outcomes come out as the protocol (results/antpush/README.md) defines them."""

import numpy as np
import pytest

from experiments import claims
from nonmono_jax.host import io

STEPS = np.arange(110_000, 1_000_001, 10_000)


def _rows(method, s_e, ppo=2000, seeds=8, upto=1_000_000):
  """metrics.csv rows of one method: S_E per (seed, step) from ``s_e(seed, step)``."""
  rows = []
  for step in STEPS[STEPS <= upto]:
    for seed in range(seeds):
      row = {c: "" for c in io.COLUMNS}
      row.update(task="AntPush", method=method, seed=str(seed), env_step=str(step),
                 eval_success=str(s_e(seed, step)))
      for m, n in (("TD3", 50_000 + seed), ("PPO", ppo + 10 * seed), ("RANDOM", 500 + seed)):
        for col in ("cum_steps", "cum_steps_after_start", "cum_decisions_after_start"):
          row[f"{col}_{m}"] = str(n)
      rows.append(row)
  return rows


def test_a_reproduction_reads_as_holding():
  ours = _rows("ours", lambda seed, t: float(t >= 450_000) * (0.9 if seed else 0.7))
  hiro = _rows("hiro", lambda seed, t: float(t <= 300_000 and t >= 200_000) * 0.8)
  r = claims.readings(ours + hiro)
  assert r["final"]["ours"]["reading"] == "holds"
  assert r["onset"]["reading"] == "holds"
  assert r["onset"]["first_step_any_seed"] == 450_000
  assert r["early_late"]["early_step"] == 250_000
  assert r["early_late"]["early"] == "holds" and r["early_late"]["behind"] == "holds"
  assert r["modes"]["order"] == "TD3 >> PPO >> RANDOM"
  assert r["modes"]["most_ppo_before_1m"] == "holds"
  assert "| 1. ours' S_E passes 0.6 at 1M | holds |" in claims.markdown(r)


def test_nothing_learned_reads_as_not_holding():
  zero = lambda seed, t: 0.0
  r = claims.readings(_rows("ours", zero, ppo=100) + _rows("hiro", zero))
  assert r["final"]["ours"]["reading"] == "does not hold"
  assert not r["final"]["ours"]["above_zero"]
  assert r["onset"]["reading"] == "does not hold"
  assert r["early_late"]["early"] == r["early_late"]["behind"] == "cannot be told apart"
  assert r["modes"]["most_ppo_before_1m"] == "does not hold"


def test_half_the_seeds_learning_cannot_be_told_apart():
  half = lambda seed, t: float(seed % 2 and t >= 700_000)
  r = claims.readings(_rows("ours", half) + _rows("hiro", lambda seed, t: 0.0))
  assert r["final"]["ours"]["reading"] == "cannot be told apart"
  assert r["onset"]["reading"] == "does not hold"  # nothing by 600K
  with pytest.raises(ValueError, match="both ours and hiro"):
    claims.readings(_rows("ours", half))


def test_a_run_still_going_is_read_only_where_the_protocol_reads_it():
  """At 300K: the early claim is read (250K), the others wait for 600K and 1M."""
  ours = _rows("ours", lambda seed, t: 0.0, upto=300_000)
  hiro = _rows("hiro", lambda seed, t: float(t >= 200_000), upto=300_000)
  r = claims.readings(ours + hiro)
  assert r["early_late"]["early"] == "holds"  # HIRO 1 against ours 0 at 250K
  assert r["final"]["ours"]["reading"] == "n/a (at 300000 of 1000000)"
  assert r["onset"]["reading"] == "n/a (at 300000: read at 600000)"
  assert r["early_late"]["behind"] == "n/a (not reached)"
  assert r["modes"]["most_ppo_before_1m"].startswith("n/a")
  assert r["modes"]["order"].endswith("(at 300000, not judged)")
