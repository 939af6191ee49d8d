#!/usr/bin/env bash
# Download, here, the wheels the GPU machine lacks (its image has jax with CUDA, flax, optax,
# orbax-checkpoint, scipy, matplotlib, tqdm and Python 3.12, but no mujoco, MJX or brax).
# They land in .whl/ (git-ignored); a device command carries .whl and installs them with
# benchmarks/device/setup.sh.
#
#   bash benchmarks/device/fetch_wheels.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
WHEELS=(
  mujoco==3.17.0 mujoco-mjx==3.17.0 brax==0.14.2          # the physics and the env API
  jaxopt==0.8.5 ml-collections==1.1.0 trimesh==5.2.0     # imported by brax / MJX
  tensorboardX==2.6.5 flask==3.1.3 flask-cors==6.0.5     # brax's other requirements
  glfw==2.11.0 PyOpenGL==3.1.10 websockets==17.4         # mujoco's
)
mkdir -p .whl
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
  --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
  --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux1_x86_64 \
  -d .whl "${WHEELS[@]}"
du -sh .whl
