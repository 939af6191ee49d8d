"""How fast can the TD3 update's matmuls run here? Their shapes alone, as a share of the
machine's matmul roofline measured in the same run.

A Low TD3 update at the paper's settings is GEMMs of batch 100 rows against 300 x 300 layers
(and thinner ones at the inputs and outputs), in three forms: the forward pass ``x @ W``, the
input gradient ``dy @ W.T`` and the weight gradient ``x.T @ dy`` (contracting the 100 rows).
Vmapped over S seeds each is a batched dot of S small GEMMs. This times each form alone,
jitted, for each ``--seeds`` count, on the devices the trainer would use (``--cpu-devices``:
seeds split over them as in training), in turns with the 1024^3 matmul of
``seed_scaling.matmul_gflops`` (best of ``--repeats``), and reports GFLOP/s, the share of the
roofline read just before (``share``) and of the best roofline of the run
(``share_of_best_roofline``: on a shared machine a reading that lost a core to another process
is not the machine's; read this one). If the forms' share is below a goal's share of the
roofline, the dots alone keep the trainer from it, whatever the rest does.

    python -m benchmarks.thin_gemm --seeds 1 4 --cpu-devices 2

Writes ``benchmarks/results/thin_gemm_<platform>_<date>.json``.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jp
import numpy as np
from jax.sharding import NamedSharding, PartitionSpec

from benchmarks import common
from benchmarks.seed_scaling import matmul_gflops
from nonmono_jax.host import run

FORMS = {  # name: ((B, K, N) -> (lhs shape, rhs shape), einsum): rows B, fan in K, fan out N
    "forward x @ W": (lambda B, K, N: ((B, K), (K, N)), "bk,kn->bn"),
    "input grad dy @ W.T": (lambda B, K, N: ((B, N), (K, N)), "bn,kn->bk"),
    "weight grad x.T @ dy": (lambda B, K, N: ((B, K), (B, N)), "bk,bn->kn"),
}


def timed(f, args, repeats: int) -> float:
  jax.block_until_ready(f(*args))
  best = float("inf")
  for _ in range(repeats):
    t0 = time.perf_counter()
    jax.block_until_ready(f(*args))
    best = min(best, time.perf_counter() - t0)
  return best


def form_program(spec: str, seeds: int, shapes, inner: int):
  """``inner`` batched dots of ``seeds`` GEMMs in one jitted call (a scan: one call's overhead
  shared), the seeds split over the devices."""
  mesh = jax.make_mesh((len(jax.devices()),), ("seeds",))
  shard = NamedSharding(mesh, PartitionSpec("seeds"))
  keys = jax.random.split(jax.random.PRNGKey(0), 2)
  a, b = (jax.device_put(jax.random.normal(k, (seeds, *s)) * 0.1, shard)
          for k, s in zip(keys, shapes))
  dot = jax.vmap(lambda x, y: jp.einsum(spec, x, y))

  def program(a, b):
    def body(carry, _):
      out = dot(a + carry, b)  # depends on the carry: no dot hoisted out of the loop
      return carry + 1e-9 * out.mean(), None
    return jax.lax.scan(body, jp.float32(0), None, length=inner)[0]

  return jax.jit(program), (a, b)


def measure(seeds: int, B: int, K: int, N: int, inner: int, repeats: int) -> list[dict]:
  rows = []
  for name, (shapes, spec) in FORMS.items():
    f, args = form_program(spec, seeds, shapes(B, K, N), inner)
    roof, t = matmul_gflops(repeats=repeats), timed(f, args, repeats)
    gflops = 2 * seeds * B * K * N * inner / t / 1e9
    rows.append({"form": name, "seeds": seeds, "devices": jax.device_count(), "rows": B,
                 "fan_in": K, "fan_out": N, "gflops": gflops, "roofline_gflops": roof,
                 "share": gflops / roof})
    print(f"{name:22s} seeds {seeds:2d} [{B}x{K}x{N}] on {jax.device_count()} device(s): "
          f"{gflops:6.1f} GFLOP/s = {gflops / roof:5.1%} of the roofline ({roof:.0f})",
          flush=True)
  return rows


def main(argv=None) -> None:
  p = argparse.ArgumentParser(description=common.description(__doc__))
  p.add_argument("--seeds", nargs="+", type=int, default=[1, 4])
  p.add_argument("--shape", nargs=3, type=int, default=[100, 300, 300], metavar=("B", "K", "N"),
                 help="rows (the TD3 batch), fan in, fan out (default: the Low's 300 x 300)")
  p.add_argument("--inner", type=int, default=50, help="dots per timed call")
  p.add_argument("--repeats", type=int, default=10)
  p.add_argument("--cpu-devices", type=int, default=1, metavar="N")
  p.add_argument("--out", default=common.RESULTS)
  args = p.parse_args(argv)
  run.use_cpu_devices(args.cpu_devices)
  if any(s % jax.device_count() for s in args.seeds):
    p.error("each --seeds must be a multiple of --cpu-devices")
  rows = []
  for s in args.seeds:
    rows += measure(s, *args.shape, args.inner, args.repeats)
    common.write_result("thin_gemm", args.out, argv, quiet=True, complete=False, results=rows)
  best = max(r["roofline_gflops"] for r in rows)
  for r in rows:  # a load that took a core from one roofline reading is not the machine's
    r["share_of_best_roofline"] = r["gflops"] / best
  for name in FORMS:
    shares = np.array([r["share_of_best_roofline"] for r in rows if r["form"] == name])
    print(f"{name:22s} {shares.min():.1%} to {shares.max():.1%} of the run's best roofline "
          f"({best:.0f} GFLOP/s)")
  common.write_result("thin_gemm", args.out, argv, complete=True, results=rows)


if __name__ == "__main__":
  main()
