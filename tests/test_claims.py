"""The Ant Push study's readings (experiments/claims.py) on made-up rows: each claim's three
outcomes come out as the protocol (results/antpush/README.md) defines them."""

import numpy as np
import pytest

from experiments import claims
from nonmono_jax.host import rows as rows_lib

STEPS = np.arange(110_000, 1_000_001, 10_000)


def _rows(method, s_e, ppo=2000, seeds=8, upto=1_000_000, modes=None):
  """metrics.csv rows of one method: S_E per (seed, step) from ``s_e(seed, step)``; the mode
  counts from ``modes`` (mode: per-seed counts) if given."""
  rows = []
  for step in STEPS[STEPS <= upto]:
    for seed in range(seeds):
      row = {c: "" for c in rows_lib.COLUMNS}
      row.update(task="AntPush", method=method, seed=str(seed), env_step=str(step),
                 eval_success=str(s_e(seed, step)))
      counts = ({m: modes[m][seed] for m in modes} if modes else
                {"TD3": 50_000 + seed, "PPO": ppo + 10 * seed, "RANDOM": 500 + seed})
      for m, n in counts.items():
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
  with pytest.raises(ValueError, match="rows of ours"):
    claims.readings(_rows("hiro", half))


def test_ours_alone_reads_claims_1_2_and_4_and_leaves_3_to_hiro():
  """The side-by-side study's ours before its HIRO runs (its protocol: claims 1, 2 and 4)."""
  alone = claims.readings(_rows("ours", lambda seed, t: float(t >= 400_000)))
  assert alone["final"]["ours"]["reading"] == "holds" and "hiro" not in alone["final"]
  assert alone["onset"]["reading"] == "holds"
  assert alone["early_late"]["early"] == alone["early_late"]["behind"] == (
      "n/a (no rows of HIRO)")
  text = claims.markdown(alone)
  assert "ours at 1000000 env steps (8 seeds; no rows of HIRO)" in text
  assert "| 3b. then behind ours (1000000) | n/a (no rows of HIRO) |" in text


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


def test_the_mode_order_on_the_monte_carlo_edge_and_exact():
  """The study's per-seed mode counts at 1M (results/antpush/README.md, claim 4a): the
  protocol's 2000 replicates (seed 0) read TD3 >> PPO, every resample reads TD3 ~ PPO."""
  modes = {"TD3": [17351, 46526, 62326, 64301, 46261, 64041],
           "PPO": [47650, 18475, 2675, 695, 18740, 960], "RANDOM": [0, 0, 0, 5, 0, 0]}
  zero = lambda seed, t: 0.0
  rows = (_rows("ours", zero, seeds=6, modes=modes)
          + _rows("hiro", lambda seed, t: float(seed == 0 and t == 1_000_000), seeds=6))
  assert claims.readings(rows)["modes"]["order"] == "TD3 >> PPO >> RANDOM"
  r = claims.readings(rows, reps="exact")
  assert r["modes"]["order"] == "TD3 ~ PPO >> RANDOM"
  assert r["modes"]["td3"][1] == 31938.5 and r["modes"]["ppo"][2] == 33062.5
  assert "every resample (exact)" in claims.markdown(r)
  assert "2000 replicates drawn with seed 0" in claims.markdown(claims.readings(rows))


def test_reps_on_the_command_line(tmp_path, capsys):
  with pytest.raises(SystemExit):
    claims.main([str(tmp_path), "--reps", "0"])
  assert "positive integer or 'exact'" in capsys.readouterr().err
  assert claims._reps("exact") == "exact" and claims._reps("50000") == 50000


def test_the_claims_on_the_papers_axis(capsys):
  """On the paper's axis the first study ends at 900K: its 1M claims are not read."""
  import os
  study = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "results", "antpush")
  assert claims.main([study, "--axis", "paper"]) == 0
  out = capsys.readouterr().out
  assert "at 900000 env steps after the warm-up (the paper's axis)" in out
  assert "n/a (at 900000 of 1000000)" in out
