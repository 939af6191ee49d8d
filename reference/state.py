"""Checkpoints of the paper's training loop: what it holds and how it is written back.

A checkpoint is taken at the top of the loop body of ``hiro.train`` (iteration ``t``, before
anything of that iteration ran). It holds every local of that frame (all networks, optimisers,
both PPO agents with their rollout buffers, counters, flags, the current state, goal and
segment sequences, success rates) except the env and the run's parameters; the two replay
buffers' filled part; the torch, numpy and python RNG states; the training env's whole
``MjData``, its step counter ``t`` and its two numpy generators; and the harness's own
counters. Written with ``torch.save`` to a temporary file, then renamed.

Resuming runs the code from its start (the same parameters build the same objects) with the
loop starting at ``t``; at the top of that first iteration the saved locals are written back
into the frame (``PyFrame_LocalsToFast``, CPython 3.11) and every state above restored.
"""

import ctypes
import os
import pickle
import random

import mujoco
import numpy as np
import torch

# Locals of hiro.train that are not saved: the env (its state is saved apart) and the run's
# parameters (rebuilt from the same arguments on resume; --steps may grow).
SKIP = frozenset({"env", "params", "policy_params", "max_timestep"})
BUFFERS = ("experience_buffer_l", "experience_buffer_h")
_BUFFER_FIELDS = ("state", "goal", "action", "reward", "next_state", "next_goal", "done",
                  "state_start", "goal_start", "state_end")


def buffer_state(buffer):
  """The filled part of an ExperienceBufferLow / High (rows ``[0, offset)``)."""
  n = buffer.offset
  fields = {name: getattr(buffer, name)[:n].clone() for name in _BUFFER_FIELDS
            if hasattr(buffer, name)}
  return {"offset": n, "capacity": buffer.capacity, "fields": fields}


def restore_buffer(buffer, saved):
  """Write a saved filled part into a freshly made (all-zero) buffer of the same layout."""
  if saved["offset"] > buffer.capacity:
    raise ValueError(f"the buffer holds {buffer.capacity} rows, the checkpoint "
                     f"{saved['offset']}")
  for name, rows in saved["fields"].items():
    getattr(buffer, name)[:saved["offset"]] = rows
  buffer.offset = saved["offset"]


def env_state(env):
  """The maze env's state: the MuJoCo data, step counter and the ant's two generators."""
  ant = env.wrapped_env
  return {"data": pickle.dumps(ant.sim.data.ptr), "t": getattr(env, "t", None),
          "np_random": ant.np_random.get_state(),
          "action_space": ant.action_space.np_random.get_state(),
          "udd_state": ant.sim.udd_state}


def restore_env(env, saved):
  """Write a saved env state into an env built the same way."""
  ant = env.wrapped_env
  mujoco.mj_copyData(ant.sim.data.ptr, ant.sim.model.ptr, pickle.loads(saved["data"]))
  if saved["t"] is not None:
    env.t = saved["t"]
  ant.np_random.set_state(saved["np_random"])
  ant.action_space.np_random.set_state(saved["action_space"])
  ant.sim.udd_state = saved["udd_state"]


def rng_state():
  """The global generators the code draws from."""
  return {"torch": torch.get_rng_state(), "numpy": np.random.get_state(),
          "python": random.getstate()}


def restore_rng(saved):
  torch.set_rng_state(saved["torch"])
  np.random.set_state(saved["numpy"])
  random.setstate(saved["python"])


def capture(frame, t, harness):
  """Everything needed to continue hiro.train's loop from the top of iteration ``t``."""
  local = frame.f_locals
  saved = {k: v for k, v in local.items() if k not in SKIP and k not in BUFFERS}
  return {"format": 1, "t": t, "locals": saved,
          "buffers": {name: buffer_state(local[name]) for name in BUFFERS},
          "rng": rng_state(), "env": env_state(local["env"]), "harness": harness}


def write(path, blob):
  """Save atomically: a temporary file beside ``path``, then a rename."""
  tmp = f"{path}.tmp"
  torch.save(blob, tmp)
  os.replace(tmp, path)


def read(path):
  return torch.load(path, weights_only=False)


def restore(frame, blob):
  """Write a checkpoint back into the loop's frame, its env and the global generators."""
  local = frame.f_locals
  if local["t"] != blob["t"]:
    raise RuntimeError(f"the loop is at t={local['t']}, the checkpoint at {blob['t']}")
  for name in BUFFERS:
    restore_buffer(local[name], blob["buffers"][name])
  local.update(blob["locals"])
  ctypes.pythonapi.PyFrame_LocalsToFast(ctypes.py_object(frame), ctypes.c_int(0))
  restore_env(local["env"], blob["env"])
  restore_rng(blob["rng"])
