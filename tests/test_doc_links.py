"""What the docs point to exists: every relative link, every repository path in backticks,
every ``module.name`` of this repository's modules, every config field's dotted path
(``top.alpha``, ``--top.alpha 0 0.4``, ``{"middle.target_smoothing": True}``) and every
command-line flag (``--eval_extra``, in code spans and fenced blocks), in README.md,
ARCHITECTURE.md, docs/, the READMEs of results/, benchmarks/ and notebooks/, and the code's
docstrings and comments. A rename that leaves a doc behind fails here rather than in a
newcomer's first hour."""

from __future__ import annotations

import ast
import functools
import glob
import os
import re

import pytest

from experiments import flags as flags_lib
from nonmono_jax.core import config as config_lib
from nonmono_jax.host import methods
from tests_support import ROOT

pytestmark = pytest.mark.docs

PATTERNS = ("*.md", "docs/*.md", "results/**/README.md", "benchmarks/*.md", "notebooks/*.md")
DOCS = sorted({os.path.relpath(p, ROOT) for pattern in PATTERNS
               for p in glob.glob(os.path.join(ROOT, pattern), recursive=True)})
CODE_DIRS = ("nonmono_jax", "envs", "experiments", "benchmarks", "reference", "tests",
             "notebooks", ".ci")
LINK = re.compile(r"\]\(([^)\s]+)\)")
CODE = re.compile(r"`([^`\n]+)`")
PATH = re.compile(r"^(?:%s)/[\w./-]*\w$" % "|".join(map(re.escape, CODE_DIRS)))
DOTTED = re.compile(r"^([a-z_][a-z0-9_]*)\.([A-Za-z_]\w*)(?:\(.*\))?$")
PACKAGE = re.compile(r"^(?:python -m )?((?:nonmono_jax|envs|experiments|benchmarks|reference)"
                     r"(?:\.\w+)+)")
# Names that in the docs are a config's sections (``top.alpha``, a field's dotted path, checked
# by ``CONFIG_PATH``) or a value (``state.done``), not the module of that name.
NOT_MODULES = {"low", "middle", "middle_ppo", "top", "homeostasis", "state"}
# AgentConfig's dotted paths as the CLI walks them (``flags.fields``: every leaf), with the
# sub-configs they lie in (``top.ppo``: an override may name a whole one).
LEAVES = [name for name, *_ in flags_lib.fields(config_lib.AgentConfig)]
CONFIG_PATHS = frozenset(leaf.rsplit(".", n)[0] for leaf in LEAVES
                         for n in range(leaf.count(".") + 1))
SECTIONS = sorted({leaf.split(".")[0] for leaf in LEAVES if "." in leaf})
# A section's dotted path anywhere in a code span, not part of a longer name (``hp.top.alpha``,
# ``modes/top.py``) and not a call (``low.make_low(...)``).
CONFIG_PATH = re.compile(r"(?<![\w./])(?:--)?((?:%s)(?:\.[a-z_]\w*)+)(?![\w(])"
                         % "|".join(SECTIONS))
FLAG = re.compile(r"(?<![\w-])(--[a-z][\w-]*(?:\.[a-z_]\w*)*)(?![\w<.-])")
# Other programs' flags the docs show (XLA's are all --xla_...): pytest's, Slurm's, Open MPI's.
EXTERNAL_FLAGS = {"--dist", "--no-loadscope-reorder", "--junitxml", "--durations",
                  "--array", "--bind-to", "--cpu-bind", "--cpus-per-task", "--gpus-per-task",
                  "--job-name", "--mem", "--nodes", "--ntasks-per-node", "--time"}
# Fields named on purpose that main does not have: removed (docs/benchmarks.md, the bfloat16
# matmul option), added on a demonstration branch (ARCHITECTURE.md), an error's example.
ABSENT_FIELDS = {"low.matmul", "middle.matmul", "low.action_l2", "middle.action_l2", "top.x"}
EXTENSIONS = {"py", "json", "jsonl", "csv", "md", "xml", "txt", "toml", "ipynb", "png", "pdf",
              "gif", "npz", "pt", "sh"}  # ``config.json`` is a file


def modules_files() -> list[str]:
  """The repository's Python files (not the paper's code, fetched into ``reference/.code``)."""
  return sorted(path for folder in CODE_DIRS
                for path in glob.glob(os.path.join(ROOT, folder, "**", "*.py"), recursive=True)
                if "/.code/" not in path)


@functools.cache
def modules() -> dict:
  """{module name: its files} of the repository's code."""
  out = {}
  for path in modules_files():
    out.setdefault(os.path.basename(path)[:-3], []).append(path)
  return out


@functools.cache
def defined(path: str) -> frozenset:
  """The names ``module.name`` can mean: the module's own (functions, classes, constants,
  imports) and its classes' (methods and fields: ``agent.step`` is ``Agent.step``)."""
  return frozenset(_names(ast.parse(open(path).read()).body))


def _names(body) -> set:
  names = set()
  for node in body:
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
      names.add(node.name)
    elif isinstance(node, ast.ClassDef):
      names |= {node.name, *_names(node.body)}
    elif isinstance(node, (ast.Assign, ast.AnnAssign)):
      targets = node.targets if isinstance(node, ast.Assign) else [node.target]
      names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
      if isinstance(node.value, ast.Dict):  # a lazy package's {exported name: its module}
        names |= {k.value for k in node.value.keys if isinstance(k, ast.Constant)}
    elif isinstance(node, (ast.Import, ast.ImportFrom)):
      names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    elif isinstance(node, (ast.If, ast.Try)):  # a guarded definition
      names |= _names(node.body) | _names(getattr(node, "orelse", []))
  return names


@functools.cache
def flags() -> frozenset:
  """Every flag of the repository's commands: the task CLI's (its config fields' too) and
  every ``"--name"`` in the code (the other commands' argparse flags)."""
  out = {f for task in methods.TASKS for f in flags_lib.make_parser(task)._option_string_actions}
  for path in modules_files():
    out |= set(re.findall(r"[\"'](--[a-z][\w.-]*)", open(path).read()))
  return frozenset(out)


def missing(doc: str, root: str = ROOT) -> list[str]:
  """What ``doc`` (a path under ``root``) names that the repository does not have."""
  base = os.path.dirname(doc)
  out, fenced = [], False
  for number, line in enumerate(open(os.path.join(root, doc)).read().split("\n"), 1):
    fenced ^= line.lstrip().startswith("```")
    spans = [line] if fenced else [m.group(1) for m in CODE.finditer(line)]
    for m in LINK.finditer(line):
      target = m.group(1).split("#")[0]
      if target and not re.match(r"^[a-z]+:", target) and not os.path.exists(
          os.path.normpath(os.path.join(root, base, target))):
        out.append(f"{doc}:{number}: link {m.group(1)}")
    for m in CODE.finditer(line):
      token = m.group(1).strip()
      if (PATH.match(token) and not os.path.exists(os.path.join(ROOT, token))
          and not token.startswith("reference/.code")):  # made by reference.setup
        out.append(f"{doc}:{number}: path {token}")
      package = PACKAGE.match(token)
      if package and package.group(1).rsplit(".", 1)[1] not in EXTENSIONS and not _importable(
          package.group(1)):
        out.append(f"{doc}:{number}: module {package.group(1)}")
      dotted = DOTTED.match(token)
      if dotted and dotted.group(1) not in NOT_MODULES and dotted.group(2) not in EXTENSIONS:
        files = modules().get(dotted.group(1), [])
        if len(files) == 1 and dotted.group(2) not in defined(files[0]):
          out.append(f"{doc}:{number}: {token} ({os.path.relpath(files[0], ROOT)} has no "
                     f"{dotted.group(2)})")
      for path in CONFIG_PATH.findall(token):
        if not _module_name(path) and not is_field(path) and path not in ABSENT_FIELDS:
          out.append(f"{doc}:{number}: config field {path}")
    for flag in sorted({f for span in spans for f in FLAG.findall(span)}):
      if not (flag in flags() or flag in EXTERNAL_FLAGS or flag.startswith("--xla_")
              or flag[2:] in ABSENT_FIELDS):
        out.append(f"{doc}:{number}: flag {flag} (no command here has it)")
  return out


def _module_name(path: str) -> bool:
  """``low.make_low``, ``top.py``: a module of the repository and a name it defines, a file."""
  module, name = path.split(".")[:2]
  files = modules().get(module, [])
  return name in EXTENSIONS or (len(files) == 1 and name in defined(files[0]))


def is_field(path: str) -> bool:
  """``top.ppo.value_weighting`` (or ``top.ppo``) is a field of ``AgentConfig`` (the overrides'
  dotted path)."""
  return path in CONFIG_PATHS


def _importable(dotted: str) -> bool:
  """``a.b.c`` is a module or package of the repository, or a name one of them defines."""
  parts = dotted.split(".")
  for n in range(len(parts), 0, -1):
    path = os.path.join(ROOT, *parts[:n])
    module = path + ".py" if os.path.exists(path + ".py") else os.path.join(path, "__init__.py")
    if os.path.exists(module):
      return n == len(parts) or (n == len(parts) - 1 and parts[-1] in defined(module))
  return False


def test_the_docs_are_found():
  assert {"README.md", "ARCHITECTURE.md", "docs/spec.md",
          "results/antpush_reference/README.md"} <= set(DOCS)


@pytest.mark.parametrize("doc", DOCS)
def test_what_the_doc_points_to_exists(doc):
  assert not missing(doc)


def test_what_the_docstrings_point_to_exists():
  """The same in the code (a module's docstring is its command's ``--help``)."""
  sources = [os.path.relpath(path, ROOT) for path in modules_files()
             if os.path.abspath(path) != os.path.abspath(__file__)]
  assert len(sources) > 100
  assert not [m for source in sources for m in missing(source)]


def test_the_absent_fields_named_are_absent():
  """The exceptions cannot go stale: a field named absent that exists is checked again."""
  assert not [path for path in ABSENT_FIELDS if is_field(path)]
  assert is_field("top.ppo.value_weighting") and is_field("c") and not is_field("top.nope")


def test_a_stale_name_is_found(tmp_path):
  """The checks can fail: a link, a path, a function and modules that do not exist are named,
  and what exists is not."""
  doc = tmp_path / "doc.md"
  doc.write_text("[a](no_such.md) `nonmono_jax/core/no_such.py` `methods.no_such` "
                 "`methods.build_config` `top.no_such` `config.json` `nonmono_jax.host.io` "
                 "`python -m experiments.no_such` [b](doc.md) `nonmono_jax.host.run` "
                 "`envs.make` `agent.step(state, t, hp)` `python -m experiments.antpush` "
                 "`--top.alpha 0 1` `--top.alfa 0 1` `{\"middle.target_smoothing\": True, "
                 "\"low.lr\": 1}` `hp.top.nope` `modes/top.py` `low.make_low` `--low.<name>`\n"
                 "```bash\npython -m experiments.antpush --eval_extra held --evaluate 3\n```\n")
  got = missing("doc.md", str(tmp_path))
  assert [g.split(": ", 1)[1].split(" (")[0] for g in got] == [
      "link no_such.md", "path nonmono_jax/core/no_such.py", "methods.no_such",
      "config field top.no_such", "module nonmono_jax.host.io", "module experiments.no_such",
      "config field top.alfa", "config field low.lr", "flag --top.alfa", "flag --evaluate"]
