"""The reference harness: the paper's own PyTorch code run on this machine.

``python -m reference.setup`` fetches the code at the pinned commit into an ignored folder,
applies the patches of ``reference.patches`` and makes a separate venv (torch, gym 0.15.7,
mujoco, numpy); ``python -m reference.run`` runs its training loop (``hiro.train`` of
``hiro_three_policy_20220818``, row 1 of ``train_param_hiro.csv``: AntPush) seeded, resumable
and logged. See docs/reference.md.
"""

import os
import pathlib

UPSTREAM = ("https://github.com/jangikim2/An-Autonomous-Non-monolithic-Agent-with-Multi-mode-"
            "Exploration-based-on-Options-Framework")
COMMIT = "8cc9d5adb6d7179eb101db05c72e09735459b9fa"
FOLDER = "hiro_three_policy_20220818"  # ours (the paper's method) in the repository

PACKAGE = pathlib.Path(__file__).resolve().parent
STANDINS = PACKAGE / "standins"  # mujoco_py and wandb stand-ins, put first on sys.path
HOME = pathlib.Path(os.environ.get("REFERENCE_HOME", PACKAGE / ".code"))  # ignored by git


def code_dir(home=None):
  """Where the code of the pinned commit is extracted (the folder holding run.py)."""
  return pathlib.Path(home or HOME) / COMMIT[:12] / FOLDER


def default_venv(home=None):
  """The reference venv's default place."""
  return pathlib.Path(home or HOME) / "venv"
