"""The benchmarks' plumbing: what they time is the trainer's own chunk, and they run. (Their
numbers are measured by running them, never here.)"""

import jax
import numpy as np

import envs
from benchmarks import common, train_throughput
from nonmono_jax.core import train
from nonmono_jax.host import methods


def test_a_compiled_chunk_is_the_trainers_chunk():
  config = methods.build_config("paper", "ours", "PointMaze", {
      "warmup_steps": 20, "top.starting_steps": 20, "low.hidden": (16, 16),
      "middle.hidden": (16, 16), "low.batch_size": 8, "middle.batch_size": 8})[0]
  trainer = train.make_trainer(envs.make("PointMaze", episode_length=50), config, num_seeds=2,
                               chunk_steps=60)
  key = jax.random.PRNGKey(3)
  compiled = common.compile_chunk(trainer, trainer.init(key))
  ours, m_ours = compiled(trainer.init(key), 0)
  theirs, m_theirs = trainer.chunk(trainer.init(key), 0)
  for a, b in zip(jax.tree.leaves((ours, m_ours)), jax.tree.leaves((theirs, m_theirs))):
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
  assert train.compiled_bytes(compiled)["total"] > 0
  assert "fusion" in compiled.as_text()


def test_train_throughput_times_a_chunk():
  r = train_throughput.measure("PointPush", "hiro", seeds=1, num_envs=1, chunk=10, repeats=1,
                               time_eval=False)
  assert r["env_steps_per_s"] > 0 and r["env_steps_per_cpu_s"] > 0 and r["seeds"] == 1


def test_profile_phases_follow_the_gated_functions():
  """A thunk is charged to the agent's phase that ran it: by its own op_name, else by the
  computation it calls (a fused dot), else by the computation it sits in (a copy)."""
  from benchmarks import profile_step
  hlo = """HloModule m

%fused_computation.1 (p: f32[2]) -> f32[2] {
  %p = f32[2]{0} parameter(0)
  ROOT %d = f32[2]{0} multiply(%p, %p), metadata={op_name="jit(chunk)/jit(low_update)/dot_general"}
}

%region_5.1 (a: f32[2]) -> f32[2] {
  %a = f32[2]{0} parameter(0)
  %m = f32[2]{0} add(%a, %a), metadata={op_name="jit(local_chunk)/jit(middle_update)/add"}
  ROOT %copy.7 = f32[2]{0} copy(%m)
}

ENTRY %main (x: f32[2]) -> f32[2] {
  %x = f32[2]{0} parameter(0)
  %ynn_fusion.3 = f32[2]{0} fusion(%x), kind=kCustom, calls=%fused_computation.1
  ROOT %copy.9 = f32[2]{0} copy(%ynn_fusion.3)
}
"""
  phases = profile_step.phases(hlo)
  assert phases["ynn_fusion.3"] == "low_update"
  assert phases["copy.7"] == "middle_update"
  assert phases["copy.9"] == "step"
  runs = [{"a": [1, 50], "b": [2, 10]}, {"a": [1, 30]}]
  assert profile_step.min_times(runs) == {"a": [1, 30], "b": [2, 10]}


def test_compiler_options_compares_bits_and_times_each_candidate(tmp_path):
  from benchmarks import compiler_options
  assert compiler_options.parse_option("a=512") == ("a", 512)
  assert compiler_options.parse_option("b=False") == ("b", False)
  compiler_options.main(["--env", "PointPush", "--method", "hiro", "--chunk", "10", "--rounds",
                         "2", "--try", "xla_cpu_multi_thread_eigen=false", "--try-config",
                         "low.tau=0.01", "--out", str(tmp_path)])
  (path,) = tmp_path.glob("compiler_options_*.json")
  import json
  eigen, tau = json.load(open(path))["results"]
  assert eigen["options"] == {"xla_cpu_multi_thread_eigen": False} and not eigen["overrides"]
  assert eigen["same_bits"] is True  # Eigen's threads split a dot's rows, not its sums
  assert len(eigen["rounds_cpu"]) == 2 and eigen["speedup_wall"] > 0
  assert tau["overrides"] == {"low.tau": 0.01} and tau["same_bits"] is False  # other targets


def test_thin_gemm_times_the_three_forms_of_a_td3_layer(tmp_path):
  """Each form is the product it names (the weight gradient contracts the batch rows), and a
  run gives one row per form and seed count with its share of the roofline."""
  from benchmarks import thin_gemm
  B, K, N = 5, 3, 4
  x, w, dy = (np.random.default_rng(i).normal(size=s) for i, s in
              enumerate([(B, K), (K, N), (B, N)]))
  want = {"forward x @ W": (x, w, x @ w), "input grad dy @ W.T": (dy, w, dy @ w.T),
          "weight grad x.T @ dy": (x, dy, x.T @ dy)}
  for name, (shapes, spec) in thin_gemm.FORMS.items():
    a, b, out = want[name]
    assert shapes(B, K, N) == (a.shape, b.shape)
    np.testing.assert_allclose(np.einsum(spec, a, b), out, rtol=1e-12)
  thin_gemm.main(["--seeds", "1", "--shape", "4", "8", "8", "--inner", "2", "--repeats", "1",
                  "--out", str(tmp_path)])
  (path,) = tmp_path.glob("thin_gemm_*.json")
  import json
  rows = json.load(open(path))["results"]
  assert [r["form"] for r in rows] == list(thin_gemm.FORMS) and all(r["share"] > 0 for r in rows)


def test_paper_code_divides_each_row_of_ours_by_the_code_and_alternates(tmp_path, monkeypatch):
  """The ratios are ours / the code per row of ours and per metric; the sides alternate their
  order per round. (The code's own side runs in tests/test_reference.py, with its venv.)"""
  from benchmarks import paper_code
  calls = []
  code = {"env_steps_per_s": 50.0, "env_steps_per_cpu_s": 25.0, "windows": 4, "threads": 2}
  ours = {"results": [{"env_steps_per_s": 200.0, "env_steps_per_cpu_s": 150.0, "seeds": 4},
                      {"env_steps_per_s": 300.0, "env_steps_per_cpu_s": 100.0, "seeds": 8}]}
  monkeypatch.setattr(paper_code, "run_code", lambda *a: calls.append("code") or dict(code))
  monkeypatch.setattr(paper_code.common, "run_fresh",
                      lambda root, name, args, out: calls.append(name) or ours)
  paper_code.main(["--rounds", "2", "--out", str(tmp_path), "--", "train_throughput", "--seeds",
                   "4", "8"])
  assert calls == ["code", "train_throughput", "train_throughput", "code"]
  import json
  (path,) = tmp_path.glob("paper_code_*.json")
  result = json.load(open(path))
  assert result["complete"] and result["ours_command"] == "train_throughput --seeds 4 8"
  assert result["median_ratio"] == [{"env_steps_per_s": 4.0, "env_steps_per_cpu_s": 6.0},
                                    {"env_steps_per_s": 6.0, "env_steps_per_cpu_s": 4.0}]
