"""The docs run: every ``bash`` and ``python`` block of README.md and docs/*.md is executed here,
at small sizes, or says why it is not.

A block is marked on the line just above its fence:

    <!-- run -->                          executed as it stands
    <!-- run: OLD => NEW ;; OLD2 => NEW2 -->  executed with these replacements (each OLD must be
                                          in the block: a doc edit that drops it fails here)
    <!-- run slow: ... -->                the same, in the slow tier (it compiles the ant or
                                          several programs; every bash block is in it too)
    <!-- not run: why -->                 a GPU, a cluster, the upstream code, a template, ...

Each block runs in its own process, in an empty temporary folder (``results/`` linked in, to
read), with the repository on ``PYTHONPATH`` and this interpreter first on ``PATH`` as
``python``. In a ``bash`` block every ``python -m experiments.<task>`` command runs with the
tests' tiny size appended (``TINY_RUN``: later flags win), a ``--resume`` with
``--no-progress`` alone (a resume takes no size flags), a ``--help`` as it stands.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
import subprocess
import sys

import pytest

from tests_support import CACHE_DIR, ROOT, TINY_RUN

pytestmark = pytest.mark.docs

MARK = re.compile(
    r"^<!-- (?:(?P<run>run)(?P<slow> slow)?(?::(?P<subs>.*))?|not run: (?P<why>.+)) -->$")
TASK_COMMAND = re.compile(r"python -m experiments\.(?:ant|point)(?:push|fall|maze)\b")
DOCS = ["README.md", *sorted(os.path.relpath(p, ROOT) for p in glob.glob(f"{ROOT}/docs/*.md"))]


@dataclasses.dataclass(frozen=True)
class Block:
  path: str
  line: int  # of the opening fence, 1-based
  lang: str
  code: str
  mark: re.Match | None  # the marker line above the fence

  @property
  def name(self) -> str:
    return f"{self.path}:{self.line}"


def blocks(path: str) -> list[Block]:
  """The fenced ``bash`` and ``python`` blocks of ``path``, with their markers."""
  lines = open(os.path.join(ROOT, path)).read().split("\n")
  out, i = [], 0
  while i < len(lines):
    if not lines[i].startswith("```"):
      i += 1
      continue
    end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
    lang = lines[i][3:].strip()
    if lang in ("bash", "python"):
      mark = MARK.match(lines[i - 1].strip()) if i else None
      out.append(Block(path, i + 1, lang, "\n".join(lines[i + 1:end]) + "\n", mark))
    i = end + 1
  return out


ALL = [b for path in DOCS for b in blocks(path)]
# A bash block runs the CLI in processes of its own (tens of seconds each, with nothing of the
# session's programs to reuse): the slow tier runs it, as every test that starts processes.
RUN = [pytest.param(b, id=b.name,
                    marks=[pytest.mark.slow] if b.mark["slow"] or b.lang == "bash" else [])
       for b in ALL if b.mark is not None and b.mark["run"]]


def test_every_block_runs_or_says_why_not():
  unmarked = [b.name for b in ALL if b.mark is None]
  assert not unmarked, f"mark these <!-- run --> or <!-- not run: why -->: {unmarked}"
  assert len(RUN) >= 7  # the tier is not empty by accident


def small(block: Block) -> str:
  """The block's code with its marker's replacements and, in bash, the tiny run size."""
  code = block.code
  for sub in filter(None, (block.mark["subs"] or "").split(";;")):
    old, new = (s.strip() for s in sub.split("=>"))
    assert old in code, f"{block.name}: {old!r} is no longer in the block"
    code = code.replace(old, new)
  if block.lang == "bash":
    code = "\n".join(map(_tiny, code.replace("\\\n", " ").split("\n")))
  return code


def _tiny(line: str) -> str:
  command, _, comment = line.partition(" #")
  return " && ".join(map(_tiny_command, command.split(" && "))) + (f"  #{comment}" if _ else "")


def _tiny_command(command: str) -> str:
  if not TASK_COMMAND.search(command) or "--help" in command:
    return command
  extra = ["--no-progress"] if "--resume" in command else TINY_RUN
  return f"{command.rstrip()} {' '.join(extra)}"


@pytest.mark.parametrize("block", RUN)
def test_the_block_runs(block, tmp_path):
  code = small(block)
  os.symlink(os.path.join(ROOT, "results"), tmp_path / "results")
  env = {**os.environ, "PYTHONPATH": ROOT, "JAX_COMPILATION_CACHE_DIR": CACHE_DIR,
         "PATH": os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")}
  command = ([sys.executable, "-c", code] if block.lang == "python" else
             ["bash", "-e", "-o", "pipefail", "-c", code])
  done = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True,
                        timeout=900)
  assert done.returncode == 0, (f"{block.name} failed ({done.returncode}):\n{code}\n"
                                f"--- stdout\n{done.stdout[-3000:]}\n--- stderr\n"
                                f"{done.stderr[-3000:]}")
