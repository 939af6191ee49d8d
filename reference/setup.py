"""Fetch the paper's code at the pinned commit, patch it and make the reference venv.

    python -m reference.setup [--from-mirror GIT_DIR] [--venv PATH]

Idempotent: a step already done (the code extracted at the commit, the venv with its
packages) is skipped. Without ``--from-mirror`` (or ``REFERENCE_MIRROR``) the upstream
repository is cloned with git into ``reference/.code/upstream.git``. ``$REFERENCE_HOME``
moves the whole ignored folder (the code, the default venv), for both commands.
"""

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys

import reference
from reference import patches

# The reference venv's packages (torch: the CPU build; gym: the version the code's
# requirements.txt names; mujoco: the engine the project uses).
PACKAGES = ("torch==2.13.0", "gym==0.15.7", "mujoco==3.17.0", "numpy")


def _git(*args, **kwargs):
  return subprocess.run(["git", *args], check=True, **kwargs)


def fetch(home, mirror=None):
  """Extract FOLDER at COMMIT into ``code_dir(home)``; return that path."""
  target = reference.code_dir(home)
  marker = target.parent / "COMMIT"
  if target.is_dir() and marker.is_file() and marker.read_text().strip() == reference.COMMIT:
    print(f"code: {target} (already there)")
    return target
  mirror = mirror or os.environ.get("REFERENCE_MIRROR")
  if mirror is None:
    mirror = pathlib.Path(home) / "upstream.git"
    if not mirror.exists():
      print(f"cloning {reference.UPSTREAM}")
      _git("clone", "--bare", reference.UPSTREAM, str(mirror))
  staging = target.parent.with_name(target.parent.name + ".partial")
  shutil.rmtree(staging, ignore_errors=True)
  staging.mkdir(parents=True)
  archive = subprocess.run(["git", "-C", str(mirror), "archive", reference.COMMIT,
                            reference.FOLDER], check=True, capture_output=True).stdout
  subprocess.run(["tar", "-x", "-C", str(staging)], input=archive, check=True)
  done = patches.apply(staging / reference.FOLDER)
  (staging / "PATCHES.json").write_text(json.dumps(done, indent=1) + "\n")
  (staging / "COMMIT").write_text(reference.COMMIT + "\n")
  shutil.rmtree(target.parent, ignore_errors=True)
  staging.rename(target.parent)
  print(f"code: {target} (commit {reference.COMMIT}, {len(done)} patches)")
  return target


def venv_python(venv):
  """The venv's interpreter."""
  return pathlib.Path(venv) / "bin" / "python"


def make_venv(venv, pip_args=()):
  """Create the venv and install PACKAGES; skipped when they import at the right versions."""
  python = venv_python(venv)
  check = ("import torch, gym, mujoco, numpy; assert torch.__version__.startswith('2.13.0'); "
           "assert gym.__version__ == '0.15.7' and mujoco.__version__ == '3.17.0'")
  if python.exists() and subprocess.run([str(python), "-c", check],
                                        capture_output=True).returncode == 0:
    print(f"venv: {venv} (already there)")
    return python
  if not python.exists():
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
  subprocess.run([str(python), "-m", "pip", "install", "-q", *pip_args, *PACKAGES], check=True)
  cuda = subprocess.run([str(python), "-c", "import torch; print(torch.version.cuda)"],
                        check=True, capture_output=True, text=True).stdout.strip()
  if cuda != "None":
    print(f"warning: torch was installed with CUDA {cuda}; the reference runs on the CPU",
          file=sys.stderr)
  subprocess.run([str(python), "-c", check], check=True)
  print(f"venv: {venv}")
  return python


def main(argv=None):
  parser = argparse.ArgumentParser(prog="python -m reference.setup", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
  parser.add_argument("--from-mirror", help="a local git directory holding the commit "
                      "(default: $REFERENCE_MIRROR, else clone the upstream repository)")
  parser.add_argument("--venv", help="where to make the reference venv (default: "
                      "reference/.code/venv, or $REFERENCE_HOME/venv)")
  parser.add_argument("--pip-args", default="", help="extra pip arguments, e.g. an index "
                      "serving torch's CPU wheels")
  parser.add_argument("--skip-venv", action="store_true", help="only fetch and patch")
  args = parser.parse_args(argv)
  fetch(reference.HOME, args.from_mirror)
  if not args.skip_venv:
    make_venv(args.venv or reference.default_venv(), args.pip_args.split())
  return 0


if __name__ == "__main__":
  sys.exit(main())
