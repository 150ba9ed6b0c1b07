"""One look for every dyadbench figure: output format by extension, paper sizes, one style per series.

- :func:`figure_format`: the format of an output path from its extension (``.pdf``, ``.svg``, ``.png``);
  any other extension is a ConfigError naming the path, before anything is drawn.
- :func:`paper_style`: matplotlib settings for a two-column paper (8-pt text, 7-pt ticks and legends;
  figures :data:`COLUMN_WIDTH` or :data:`PAGE_WIDTH` inches wide), TrueType fonts in PDF, 300-dpi PNG.
- :func:`model_style`: the colour, marker, line style and width of a series, the same in every figure.
  Three kinds of series, told apart at a glance:

  * *models* (every name that is not a registered baseline or oracle): solid 1.3-pt lines and filled markers
    in Paul Tol's colour-blind-safe qualitative colours. The reference models have fixed colours
    (:data:`REFERENCE_STYLES`, Tol *bright*); any other name takes a colour of :data:`EXTRA_COLOURS` (Tol
    *vibrant*/*muted* hues unlike the reference ones) and a marker from the SHA-256 of the name;
  * *baselines* (registry tag ``baseline``, :mod:`dyadbench.registry`): thin 0.8-pt grey lines with
    unfilled-looking line markers (x, +, *, triangles; :data:`BASELINE_STYLES`), so no baseline is read as a
    model; an unlisted baseline gets a grey and marker from the SHA-256 of its name;
  * the *oracle* (registry tag ``oracle`` or a result recorded as oracle): black and dashed.

  A variant (``timar (cfg1.5)``: the model, a space, the settings in parentheses) keeps its model's colour
  and marker and gets a dashed, dotted or dash-dotted line and an open marker (chosen by the SHA-256 of the
  settings).
- :func:`figure_styles`: the styles of all series of one figure. Each series gets its :func:`model_style`
  unless that would repeat another series' (colour, marker, line style), or give a model the colour of
  another model; then the next candidate of its kind is taken (the next colour/marker pair of its pool, the
  next variant line style), in legend order (:func:`series_order`). Registered names never need this (their
  styles are distinct by construction), so they look the same in every figure; with more than 10 models in
  one figure colours repeat and markers tell them apart.
- :func:`save`: write a figure atomically in the format of its extension, without timestamps or software
  tags, so the same data gives the same bytes.
"""

from __future__ import annotations

import hashlib
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterable, Iterator

from dyadbench import atomic
from dyadbench.errors import ConfigError
from dyadbench.registry import MODELS

#: Extension -> matplotlib format.
FORMATS = {".pdf": "pdf", ".svg": "svg", ".png": "png"}
#: Widths in inches of one column and of the full page of a two-column paper (e.g. IEEE, CVPR).
COLUMN_WIDTH = 3.5
PAGE_WIDTH = 7.16
PNG_DPI = 300

#: Paul Tol's colour-blind-safe "bright" palette without its grey (https://personal.sron.nl/~pault/).
BRIGHT = {"blue": "#4477AA", "cyan": "#66CCEE", "green": "#228833", "yellow": "#CCBB44", "red": "#EE6677",
          "purple": "#AA3377"}
#: Reference models: (colour, marker), one colour each.
REFERENCE_STYLES = {"timar": (BRIGHT["blue"], "o"), "timar-stream": (BRIGHT["cyan"], "s"),
                    "dualtalk": (BRIGHT["red"], "^"), "dualtalk-offline": (BRIGHT["purple"], "D"),
                    "sfms": (BRIGHT["yellow"], "v"), "stygazetalk": (BRIGHT["green"], "P")}
#: Colours and markers of models that are not registered: Tol's vibrant orange and teal, muted indigo and olive.
EXTRA_COLOURS = ("#EE7733", "#009988", "#332288", "#999933")
MODEL_MARKERS = ("o", "s", "^", "D", "v", "P", "X")
#: Registered baselines: (grey, marker); two greys and line markers, unlike every model's.
BASELINE_GREYS = ("#9A9A9A", "#5E5E5E")
BASELINE_MARKERS = ("x", "+", "*", "<", ">", "h", "d")
BASELINE_STYLES = {"zero": (BASELINE_GREYS[0], "x"), "mean-frame": (BASELINE_GREYS[0], "+"),
                   "median-frame": (BASELINE_GREYS[1], "d"), "random": (BASELINE_GREYS[1], "*"),
                   "mime": (BASELINE_GREYS[0], "<"), "lagged-mirror": (BASELINE_GREYS[1], ">"),
                   "nn-retrieval": (BASELINE_GREYS[0], "h"), "gaze-static": (BASELINE_GREYS[1], "x")}
ORACLE_COLOUR = "#000000"
ORACLE_MARKERS = ("s", "o", "D", "^")
VARIANT_LINES = ("--", ":", "-.")
#: Line widths (points): models and the oracle, baselines.
MODEL_WIDTH, BASELINE_WIDTH = 1.3, 0.8


def figure_format(out: str | Path) -> str:
    """``pdf``, ``svg`` or ``png`` from the extension of ``out``; ConfigError for any other."""
    suffix = Path(out).suffix.lower()
    if suffix not in FORMATS:
        raise ConfigError(f"{out}: unknown figure format {suffix or '(no extension)'!r}; "
                          f"use {', '.join(FORMATS)}")
    return FORMATS[suffix]


@dataclass(frozen=True)
class SeriesStyle:
    """How one series is drawn: matplotlib ``color``, ``marker``, ``linestyle``, marker face colour and line
    width, and its ``kind`` (``model``, ``baseline`` or ``oracle``; baselines are drawn below the others)."""

    color: str
    marker: str
    linestyle: str
    markerfacecolor: str
    linewidth: float
    kind: str

    def kwargs(self) -> dict:
        return {"color": self.color, "marker": self.marker, "linestyle": self.linestyle,
                "markerfacecolor": self.markerfacecolor, "linewidth": self.linewidth,
                "zorder": 1.5 if self.kind == "baseline" else 2.0}


def _digest(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "big")


def split_label(label: str) -> tuple[str, str]:
    """``"timar (cfg1.5)"`` -> ``("timar", "cfg1.5")``; a label without settings -> ``(label, "")``."""
    if label.endswith(")") and " (" in label:
        model, _, settings = label[:-1].partition(" (")
        return model, settings
    return label, ""


def series_kind(model: str, oracle: bool = False) -> str:
    """``oracle`` (recorded as oracle, or registered with tag ``oracle``), ``baseline`` (registered with tag
    ``baseline``) or ``model`` (any other name)."""
    tags = MODELS.get(model).tags if model in MODELS else ()
    if oracle or "oracle" in tags:
        return "oracle"
    return "baseline" if "baseline" in tags else "model"


def series_order(label: str, oracle: bool = False) -> tuple[int, int, str, str]:
    """Legend order: models (reference models in :data:`REFERENCE_STYLES` order, then others by name),
    baselines (:data:`BASELINE_STYLES` order, then others), the oracle; a variant right after its model."""
    model, settings = split_label(label)
    kind = series_kind(model, oracle)
    table = {"model": REFERENCE_STYLES, "baseline": BASELINE_STYLES, "oracle": {}}[kind]
    index = list(table).index(model) if model in table else len(table)
    return ("model", "baseline", "oracle").index(kind), index, model, settings


def _rotate(pairs: list[tuple[str, str]], name: str) -> list[tuple[str, str]]:
    start = _digest(name) % len(pairs)
    return pairs[start:] + pairs[:start]


def _pairs(colours: Iterable[str], markers: tuple[str, ...]) -> list[tuple[str, str]]:
    """Every (colour, marker) pair, in the order (colour k mod C, marker k mod M) (all pairs when C and M are
    coprime)."""
    colours = tuple(colours)
    return [(colours[k % len(colours)], markers[k % len(markers)]) for k in range(len(colours) * len(markers))]


def _base_styles(model: str, kind: str) -> list[SeriesStyle]:
    """The styles a model's plain series may take, preferred first (see the module docstring)."""
    if kind == "oracle":
        fixed, pool = {"oracle": (ORACLE_COLOUR, "s")}, _rotate(_pairs([ORACLE_COLOUR], ORACLE_MARKERS), model)
    elif kind == "baseline":
        fixed, pool = BASELINE_STYLES, _rotate(_pairs(BASELINE_GREYS, BASELINE_MARKERS), model)
    else:
        fixed = REFERENCE_STYLES
        pool = (_rotate(_pairs(EXTRA_COLOURS, MODEL_MARKERS), model)
                + _rotate(_pairs(BRIGHT.values(), MODEL_MARKERS), model))
    pairs = ([fixed[model]] if model in fixed else []) + pool
    width = BASELINE_WIDTH if kind == "baseline" else MODEL_WIDTH
    line = "--" if kind == "oracle" else "-"
    return [SeriesStyle(colour, marker, line, colour, width, kind) for colour, marker in pairs]


#: Markers of each kind of series, the ones a variant may fall back to.
KIND_MARKERS = {"model": MODEL_MARKERS, "baseline": BASELINE_MARKERS, "oracle": ORACLE_MARKERS}


def _variant_styles(base: SeriesStyle, settings: str) -> list[SeriesStyle]:
    """A variant of a series styled ``base``: its colour, open markers, each variant line style in turn
    (starting from the SHA-256 of the settings) with its marker, then with the other markers of its kind."""
    start = _digest(settings) % len(VARIANT_LINES)
    lines = [VARIANT_LINES[(start + j) % len(VARIANT_LINES)] for j in range(len(VARIANT_LINES))]
    markers = [base.marker] + [m for m in KIND_MARKERS[base.kind] if m != base.marker]
    return [replace(base, linestyle=line, marker=marker, markerfacecolor="white")
            for marker in markers for line in lines]


def _candidates(label: str, oracle: bool, base: SeriesStyle | None = None) -> list[SeriesStyle]:
    model, settings = split_label(label)
    bases = [base] if base is not None else _base_styles(model, series_kind(model, oracle))
    return [v for b in bases for v in _variant_styles(b, settings)] if settings else bases


def model_style(label: str, oracle: bool = False) -> SeriesStyle:
    """The style of a series labelled ``label`` (a model name, or a variant ``model (settings)``) on its own."""
    return _candidates(label, oracle)[0]


def figure_styles(series: Iterable[tuple[str, bool]]) -> dict[str, SeriesStyle]:
    """Label -> style for the (label, oracle) series of one figure: no two series share colour, marker and
    line style, and no two models share a colour while the palette lasts (see the module docstring)."""
    chosen: dict[str, SeriesStyle] = {}
    for label, oracle in sorted(set(series), key=lambda item: series_order(*item)):
        model, settings = split_label(label)
        options = _candidates(label, oracle, chosen.get(model) if settings else None)
        chosen[label] = next((s for s in options if _fits(s, model, chosen, own_colour=True)),
                             next((s for s in options if _fits(s, model, chosen, own_colour=False)), options[0]))
    return chosen


def _fits(style: SeriesStyle, model: str, chosen: dict[str, SeriesStyle], own_colour: bool) -> bool:
    """No series of ``chosen`` has the same colour, marker and line style; with ``own_colour``, no other model
    has the same colour either."""
    for label, other in chosen.items():
        if (other.color, other.marker, other.linestyle) == (style.color, style.marker, style.linestyle):
            return False
        if (own_colour and style.kind == other.kind == "model" and other.color == style.color
                and split_label(label)[0] != model):
            return False
    return True


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
