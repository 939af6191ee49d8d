"""The layout the architecture promises (ARCHITECTURE.md): the jitted core imports nothing from
the host side or the commands, and functions stay short enough to read at once."""

import ast
import os
import subprocess
import sys

import pytest

from tests.tests_support import ROOT

MAX_OWN_LINES = 60  # a function's lines, its docstring and nested functions not counted


def _modules(*folders):
  for folder in folders:
    for dirpath, dirs, names in os.walk(os.path.join(ROOT, folder)):
      dirs[:] = [d for d in dirs if not d.startswith(".")]  # reference/.code: the paper's code
      for name in sorted(names):
        if name.endswith(".py"):
          path = os.path.join(dirpath, name)
          yield os.path.relpath(path, ROOT), ast.parse(open(path).read())


def _imports(tree):
  for node in ast.walk(tree):
    if isinstance(node, ast.Import):
      yield from (a.name for a in node.names)
    elif isinstance(node, ast.ImportFrom) and node.module:
      yield node.module
      yield from (f"{node.module}.{a.name}" for a in node.names)


def test_the_core_imports_nothing_from_the_host_side():
  found = list(_modules("nonmono_jax/core"))
  assert len(found) > 15
  for path, tree in found:
    bad = [m for m in _imports(tree)
           if m.startswith(("nonmono_jax.host", "experiments", "benchmarks"))]
    assert not bad, f"{path} imports {bad}"


def _own_lines(fn) -> int:
  lines = set(range(fn.lineno, fn.end_lineno + 1))
  for node in ast.walk(fn):
    if node is not fn and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
      lines -= set(range(node.lineno, node.end_lineno + 1))
  first = fn.body[0]
  if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(
      first.value.value, str):
    lines -= set(range(first.lineno, first.end_lineno + 1))
  return len(lines)


@pytest.mark.parametrize("folder", ["nonmono_jax", "envs", "experiments", "benchmarks",
                                    "reference"])
def test_functions_are_at_most_60_lines_of_their_own(folder):
  long = [f"{path}:{node.lineno} {node.name} ({_own_lines(node)} lines)"
          for path, tree in _modules(folder) for node in ast.walk(tree)
          if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
          and _own_lines(node) > MAX_OWN_LINES]
  assert not long, long


def test_no_undefined_or_unused_names_or_long_lines():
  """ruff with pyproject's rules: pyflakes' (F), so that an undefined name in code no test runs
  (a benchmark's worker, say) fails here rather than in a user's hands, and the line length."""
  r = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache",
                      "--output-format", "concise", ROOT], capture_output=True, text=True)
  assert r.returncode == 0, r.stdout + r.stderr


def test_the_longest_test_files_named_first_exist():
  """``conftest.LONGEST_FIRST`` names files (a renamed one would silently go back in line)."""
  import conftest  # the module pytest loaded (tests/ is on sys.path, as for tests_support)
  assert all(os.path.exists(os.path.join(ROOT, "tests", f)) for f in conftest.LONGEST_FIRST)
