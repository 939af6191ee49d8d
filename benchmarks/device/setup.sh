#!/usr/bin/env bash
# On the GPU machine, at the start of every command (the machine starts bare):
#   source benchmarks/device/setup.sh && python -m benchmarks.train_throughput ...
# Installs the carried wheels (.whl, see fetch_wheels.sh) into /tmp/site, puts them and the
# checkout on PYTHONPATH and prints what jax sees.
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
  --target /tmp/site .whl/*.whl || return 1
export PYTHONPATH=/tmp/site:$PWD${PYTHONPATH:+:$PYTHONPATH}
export PYTHONUNBUFFERED=1
export JAX_COMPILATION_CACHE_DIR=$PWD/.jax_cache
python3 -c "import jax, mujoco, brax; print('jax', jax.__version__, jax.devices(), '| mujoco', mujoco.__version__, '| brax', brax.__version__)"
