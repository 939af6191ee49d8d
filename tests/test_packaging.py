"""What pip installs agrees with itself: the GPU extra takes the pinned JAX, every optional sink
has its extra, the dev extra brings what the tests and the docs use."""

import os
import re
import sys

import pytest

from tests_support import ROOT

if sys.version_info >= (3, 11):
  import tomllib
else:  # pragma: no cover - Python 3.10
  tomllib = pytest.importorskip("tomli")


@pytest.fixture(scope="module")
def project():
  with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
    return tomllib.load(f)["project"]


def _pins(requirements) -> dict:
  """{name (lower case, extras dropped): its version specifier}."""
  out = {}
  for r in requirements:
    m = re.match(r"([A-Za-z0-9_.-]+)(\[[^]]*\])?\s*(.*)", r)
    out[m.group(1).lower()] = m.group(3).strip()
  return out


def test_the_cuda_extra_takes_the_pinned_jax(project):
  pins = _pins(project["dependencies"])
  (cuda,) = project["optional-dependencies"]["cuda12"]
  assert cuda.startswith("jax[cuda12]")
  assert _pins([cuda])["jax"] == pins["jax"] == pins["jaxlib"], (cuda, pins["jax"])


def test_the_optional_sinks_have_their_extras(project):
  extras = project["optional-dependencies"]
  assert "tensorboardx" in _pins(extras["tensorboard"])
  assert "wandb" in _pins(extras["wandb"])
  from nonmono_jax.host import sinks
  assert {flag: module.lower() for flag, (module, _) in sinks.OPTIONAL.items()} == {
      "tensorboard": "tensorboardx", "wandb": "wandb"}
  dev = extras["dev"]
  assert "nonmono-jax[tensorboard,wandb]" in dev and "nbconvert" in _pins(dev)


def test_the_gpu_docs_install_the_extra_not_a_newer_jax():
  with open(os.path.join(ROOT, "docs", "gpu.md")) as f:
    text = f.read()
  assert 'pip install -e ".[cuda12]"' in text
  assert "then `pip install -e .`" not in text  # the old advice, which fought the pin
