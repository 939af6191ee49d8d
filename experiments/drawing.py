"""The figures' common look: the methods' names and colours, the axes' labels, a curve with its
interval band, one legend below the panels, and saving as PNG and PDF with reproducible bytes.
``experiments.plot`` and ``experiments.sidebyside`` draw with it."""

from __future__ import annotations

import os

import numpy as np

from experiments.curves import AXES

LABELS = {"ours": "Ours", "hiro": "HIRO", "ref-uniform": "Ref:Uniform", "ref-ppo": "Ref:PPO",
          "ours-no-reward-mod": "Ours w/o reward mod.", "ours-no-loss-mod": "Ours w/o loss mod.",
          "ours-no-mods": "Ours w/o both"}
MODE_COLORS = {"TD3": "tab:blue", "PPO": "tab:orange", "RANDOM": "tab:green"}
MODE_STYLES = {"TD3": "-", "PPO": "--", "RANDOM": ":"}  # overlapping mode lines stay visible
STEPS_LABEL = AXES["env"]  # the x label of every step axis; ``finish`` formats those axes
SUCCESS = "success rate"  # S_E, as a figure's reader calls it (evaluation episodes' success)
INTERVAL = "95% CI"  # every band and bar is a 95 % stratified-bootstrap interval (stats.SIZE)


def seeds_text(n: int) -> str:
  """``1 seed``, ``4 seeds``."""
  return f"{n} seed{'' if n == 1 else 's'}"


def label(variant: str) -> str:
  """A method's label; a sweep variant's (``ours+top.alpha=0,0.2,0.35``) with its values."""
  method, _, values = variant.partition("+")
  return LABELS.get(method, method) + (f" [{values.replace('+', '; ')}]" if values else "")


def variants(rows, task) -> list[str]:
  """The task's methods in LABELS order, each followed by its sweep variants (in row order)."""
  names = list(dict.fromkeys(r["method"] for r in rows if r["task"] == task))
  return [v for m in LABELS for v in names if v.partition("+")[0] == m]


def band(ax, curve, name, color=None, bounds=(-np.inf, np.inf), **style):
  """A curve (steps, point, lower, upper, ...) named ``name`` and its interval, the band
  clipped to ``bounds`` (a success rate's: [0, 1])."""
  steps, point, lower, upper = curve[:4]
  line, = ax.plot(steps, point, label=name, color=color, lw=1.6, **style)
  ax.fill_between(steps, np.clip(lower, *bounds), np.clip(upper, *bounds),
                  color=line.get_color(), alpha=0.2, lw=0)


def legend_below(fig, axes, ncol: int):
  """One legend for the figure, below its panels, where it covers no curve: the labelled lines
  of ``axes``, each label once (a line missing from one panel is named from another)."""
  entries = {}
  for ax in axes:
    for handle, text in zip(*ax.get_legend_handles_labels()):
      entries.setdefault(text, handle)
  handles, labels = list(entries.values()), list(entries)
  fig.legend(handles, labels, loc="lower center", ncol=max(min(ncol, len(labels)), 1),
             fontsize=8, frameon=False, bbox_to_anchor=(0.5, 0.0))


def finish(fig, out, name, xlabel=STEPS_LABEL):
  """Save ``name`` as PNG and PDF and close the figure; the PDF without its creation date, so
  that drawing the same files again writes the same bytes (committed figures change only when
  the data does).
  Env-step axes are labelled 250k, 1M: six-digit tick labels run into each other; ``xlabel``
  names them (``AXES``)."""
  from matplotlib.ticker import EngFormatter
  for ax in fig.axes:
    if ax.get_xlabel() == STEPS_LABEL:
      ax.xaxis.set_major_formatter(EngFormatter(sep=""))
      ax.set_xlabel(xlabel)
  fig.tight_layout()
  for legend in fig.legends:  # a legend below the panels (``legend_below``): room for it
    fig.canvas.draw()
    height = legend.get_window_extent().height / fig.bbox.height
    fig.tight_layout(rect=(0, height + 0.01, 1, 1))
  paths = []
  for ext in ("png", "pdf"):
    path = os.path.join(out, f"{name}.{ext}")
    fig.savefig(path, dpi=150, metadata={"CreationDate": None} if ext == "pdf" else None)
    paths.append(path)
  import matplotlib.pyplot as plt
  plt.close(fig)
  return paths

