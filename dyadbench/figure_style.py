"""One look for every dyadbench figure: output format by extension, paper sizes, one style per model.

- :func:`figure_format`: the format of an output path from its extension (``.pdf``, ``.svg``, ``.png``);
  any other extension is a ConfigError naming the path, before anything is drawn.
- :func:`paper_style`: matplotlib settings for a two-column paper (8-pt text, 7-pt ticks and legends;
  figures :data:`COLUMN_WIDTH` or :data:`PAGE_WIDTH` inches wide), TrueType fonts in PDF, 300-dpi PNG.
- :func:`model_style`: the colour, marker and line style of a series, the same in every figure. Colours
  are Paul Tol's colour-blind-safe *muted* palette (9 colours) and markers a list of 7, so the pairs
  (colour i mod 9, marker i mod 7) differ for 63 consecutive indices. The known models have fixed indices
  (:data:`KNOWN_MODELS`); any other name gets index 16 + (SHA-256 of the name mod 47), so it is the same
  in every figure and every run. A variant (``timar (cfg1.5)``: the model, a space, the settings in
  parentheses) keeps its model's colour and marker and gets a dashed, dotted or dash-dotted line and an
  open marker (chosen by the SHA-256 of the settings); the oracle is black and dashed.
- :func:`save`: write a figure atomically in the format of its extension, without timestamps or software
  tags, so the same data gives the same bytes.
"""

from __future__ import annotations

import hashlib
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from dyadbench import atomic
from dyadbench.errors import ConfigError

#: Extension -> matplotlib format.
FORMATS = {".pdf": "pdf", ".svg": "svg", ".png": "png"}
#: Widths in inches of one column and of the full page of a two-column paper (e.g. IEEE, CVPR).
COLUMN_WIDTH = 3.5
PAGE_WIDTH = 7.16
PNG_DPI = 300

#: Paul Tol's "muted" qualitative palette (colour-blind safe), https://personal.sron.nl/~pault/.
PALETTE = ("#332288", "#88CCEE", "#44AA99", "#117733", "#999933", "#DDCC77", "#CC6677", "#882255", "#AA4499")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
VARIANT_LINES = ("--", ":", "-.")
ORACLE_COLOUR = "#000000"

#: Registered models in a fixed order: model i gets colour i mod 9 and marker i mod 7.
KNOWN_MODELS = ("timar", "timar-stream", "dualtalk", "dualtalk-offline", "sfms", "nn-retrieval", "mime",
                "lagged-mirror", "random", "mean-frame", "median-frame", "zero", "stygazetalk", "gaze-static",
                "gaze-headcopy", "oracle")
_UNIQUE = len(PALETTE) * len(MARKERS)  # 63: lcm of 9 and 7


def figure_format(out: str | Path) -> str:
    """``pdf``, ``svg`` or ``png`` from the extension of ``out``; ConfigError for any other."""
    suffix = Path(out).suffix.lower()
    if suffix not in FORMATS:
        raise ConfigError(f"{out}: unknown figure format {suffix or '(no extension)'!r}; "
                          f"use {', '.join(FORMATS)}")
    return FORMATS[suffix]


@dataclass(frozen=True)
class SeriesStyle:
    """How one series is drawn: matplotlib ``color``, ``marker``, ``linestyle`` and marker face colour."""

    color: str
    marker: str
    linestyle: str
    markerfacecolor: str

    def kwargs(self) -> dict:
        return {"color": self.color, "marker": self.marker, "linestyle": self.linestyle,
                "markerfacecolor": self.markerfacecolor}


def _digest(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "big")


def split_label(label: str) -> tuple[str, str]:
    """``"timar (cfg1.5)"`` -> ``("timar", "cfg1.5")``; a label without settings -> ``(label, "")``."""
    if label.endswith(")") and " (" in label:
        model, _, settings = label[:-1].partition(" (")
        return model, settings
    return label, ""


def model_index(model: str) -> int:
    """The style index of a model name (see the module docstring)."""
    if model in KNOWN_MODELS:
        return KNOWN_MODELS.index(model)
    return len(KNOWN_MODELS) + _digest(model) % (_UNIQUE - len(KNOWN_MODELS))


def model_style(label: str, oracle: bool = False) -> SeriesStyle:
    """The style of a series labelled ``label`` (a model name, or a variant ``model (settings)``)."""
    model, settings = split_label(label)
    index = model_index(model)
    color = ORACLE_COLOUR if oracle or model == "oracle" else PALETTE[index % len(PALETTE)]
    marker = MARKERS[index % len(MARKERS)]
    if settings:
        return SeriesStyle(color, marker, VARIANT_LINES[_digest(settings) % len(VARIANT_LINES)], "white")
    return SeriesStyle(color, marker, "--" if color == ORACLE_COLOUR else "-", color)


#: matplotlib settings of every figure (a two-column paper's sizes).
RC = {"font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "xtick.labelsize": 7, "ytick.labelsize": 7,
      "legend.fontsize": 7, "legend.frameon": False, "lines.linewidth": 1.1, "lines.markersize": 3.5,
      "axes.spines.top": False, "axes.spines.right": False, "axes.formatter.useoffset": False,
      "pdf.fonttype": 42, "svg.fonttype": "none", "svg.hashsalt": "dyadbench", "savefig.dpi": PNG_DPI}


@contextmanager
def paper_style() -> Iterator[object]:
    """``matplotlib.pyplot`` (Agg backend) with :data:`RC` applied for the ``with`` block."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with plt.rc_context(RC):
        yield plt


#: Metadata that would differ between runs (dates, software versions), removed per format.
_NO_STAMPS = {"pdf": {"CreationDate": None, "Producer": None, "Creator": None},
              "svg": {"Date": None, "Creator": None}, "png": {"Software": None}}


def save(fig, out: str | Path) -> Path:
    """Write ``fig`` to ``out`` (atomically) in the format of its extension, then close it."""
    import matplotlib.pyplot as plt

    fmt = figure_format(out)
    try:
        return atomic.write_with(out, lambda tmp: fig.savefig(tmp, format=fmt, metadata=_NO_STAMPS[fmt],
                                                              bbox_inches="tight", pad_inches=0.02))
    finally:
        plt.close(fig)


def legend_outside(fig, axes) -> None:
    """One legend for the whole figure, right of the panels (centred), with each label once (first handle)."""
    handles = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="outside right center")
