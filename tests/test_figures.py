"""Figures: format by extension (PDF/SVG/PNG, others refused), one style per model in every figure, variants
as their own series, axes at the protocol's values, datasets never mixed, and the committed figure set."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from dyadbench import figure_style, plotting
from dyadbench.cli import cli
from dyadbench.errors import ConfigError
from dyadbench.figure_set import figure_builders, figure_files
from dyadbench.leaderboard import long_table
from dyadbench.results import DataRecord, EvalResult, ModelRecord, ProtocolRecord, TimingRecord

REPO = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"


def pdf_pages(path: Path) -> int:
    """Pages of a PDF file (its page objects), after checking its header."""
    data = path.read_bytes()
    assert data.startswith(b"%PDF-"), path
    return len(re.findall(rb"/Type\s*/Page\b", data))


def assert_opens(path: Path) -> None:
    if path.suffix == ".png":
        assert path.read_bytes().startswith(PNG)
        with Image.open(path) as image:
            image.verify()
    elif path.suffix == ".pdf":
        assert pdf_pages(path) == 1, path
    else:
        assert path.read_text().lstrip().startswith("<?xml") and "<svg" in path.read_text()


def write_result(folder: Path, model: str, context: int, fd_exp: float, *, dataset: str = "synthetic",
                 split: str = "test", cfg_scale: float = 1.0, oracle: bool = False) -> None:
    """A hand-made DualTalk-suite result file (raw values; FD exp is printed unscaled)."""
    metrics = {"fd_exp": fd_exp, "pfd_exp": fd_exp + 1.0, "mse_exp": fd_exp / 100}
    name = model + ("" if cfg_scale == 1.0 else f"@cfg{cfg_scale:g}")
    path = folder / dataset / split / f"n{context}" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    EvalResult(model=ModelRecord(model, "1", None, None, oracle, "flame56", {}),
               data=DataRecord(dataset, split, None, clips=4, items=8),
               protocol=ProtocolRecord("streaming", 1.0, context, "truncate", "masked", cfg_scale, 0),
               suite="dualtalk", metrics=metrics, scaled=dict(metrics), scaling={k: 1.0 for k in metrics},
               per_clip=[], timing=TimingRecord(1.0, 1.0, 1, 1.0)).write(path)


@pytest.fixture()
def captured(monkeypatch):
    """The figures the plotting functions save (their legends and axes stay readable)."""
    figures = []
    save = figure_style.save

    def keep(fig, out):
        figures.append(fig)
        return save(fig, out)

    monkeypatch.setattr(figure_style, "save", keep)
    return figures


def legend(fig) -> dict[str, tuple]:
    """Legend label -> (colour, marker, line style) of a saved figure."""
    (box,) = fig.legends
    return {text.get_text(): (handle.get_color(), handle.get_marker(), handle.get_linestyle())
            for handle, text in zip(box.legend_handles, box.get_texts())}


def test_unknown_extensions_are_refused_before_drawing(tmp_path):
    for name in ("x.jpg", "x", "x.PDF.bak"):
        with pytest.raises(ConfigError, match="unknown figure format"):
            figure_style.figure_format(tmp_path / name)
    assert [figure_style.figure_format(f"f{e}") for e in (".pdf", ".SVG", ".png")] == ["pdf", "svg", "png"]
    write_result(tmp_path / "r", "zero", 0, 5.0)
    write_result(tmp_path / "r", "zero", 3, 5.0)
    result = CliRunner().invoke(cli, ["plot", "context", str(tmp_path / "r"), "--out", str(tmp_path / "c.jpg")])
    assert result.exit_code != 0 and "unknown figure format '.jpg'" in str(result.exception)
    assert not (tmp_path / "c.jpg").exists()


def test_every_figure_kind_is_written_as_pdf_svg_and_png(tmp_path):
    results = tmp_path / "r"
    for n in (0, 3, 7):
        write_result(results, "zero", n, 50.0)
        write_result(results, "timar", n, 10.0 - n)
    long = long_table([results])
    r = np.random.default_rng(0)
    for ext in (".pdf", ".svg", ".png"):
        for path in (plotting.plot_context_curves(long, ["fd_exp", "mse_exp"], tmp_path / f"c{ext}"),
                     plotting.plot_bars(long, ["fd_exp"], tmp_path / f"b{ext}"),
                     plotting.plot_trajectories(r.normal(size=(50, 56)), r.normal(size=(50, 56)),
                                                r.normal(size=(50, 56)), "flame56", tmp_path / f"t{ext}")):
            assert_opens(path)


def test_models_keep_their_style_across_figures_and_variants_are_separate_series(tmp_path, captured):
    first, second = tmp_path / "a", tmp_path / "b"
    for n in (0, 7):
        write_result(first, "timar", n, 5.0)
        write_result(first, "timar", n, 4.0, cfg_scale=1.5)
        write_result(first, "my-model", n, 6.0)
        write_result(second, "zero", n, 50.0)
        write_result(second, "oracle", n, 0.0, oracle=True)
        write_result(second, "my-model", n, 7.0)
        write_result(second, "timar", n, 5.0)
    plotting.plot_context_curves(long_table([first]), ["fd_exp"], tmp_path / "a.png")
    plotting.plot_context_curves(long_table([second]), ["fd_exp"], tmp_path / "b.png")
    a, b = legend(captured[0]), legend(captured[1])
    assert set(a) == {"timar", "timar (cfg1.5)", "my-model"} and set(b) == {"timar", "zero", "my-model", "oracle"}
    for model in ("timar", "my-model"):
        assert a[model] == b[model], model
    # the variant: its model's colour and marker, another line style; every model its own colour/marker pair
    assert a["timar (cfg1.5)"][:2] == a["timar"][:2] and a["timar (cfg1.5)"][2] != a["timar"][2]
    assert len({v[:2] for v in b.values()}) == len(b)
    assert b["oracle"][0] == "#000000" and b["oracle"][2] == "--"
    # ticks at the contexts the results hold, no offset axis
    ax = captured[0].axes[0]
    assert list(ax.get_xticks()) == [0, 7] and ax.yaxis.get_major_formatter().get_offset() == ""


def test_palette_gives_every_known_model_its_own_pair_and_unknown_names_a_fixed_one():
    pairs = [(figure_style.PALETTE[i % 9], figure_style.MARKERS[i % 7]) for i in range(63)]
    assert len(set(pairs)) == 63  # 9 colours x 7 markers, coprime: 63 distinct pairs in a row
    known = [figure_style.model_style(m) for m in figure_style.KNOWN_MODELS if m != "oracle"]
    assert len({(s.color, s.marker) for s in known}) == len(known) == 15
    names = [f"model-{i}" for i in range(30)]
    assert [figure_style.model_index(n) for n in names] == [figure_style.model_index(n) for n in names]
    assert all(16 <= figure_style.model_index(n) < 63 for n in names)


def test_datasets_never_share_a_figure_and_one_context_has_no_curve(tmp_path):
    results = tmp_path / "r"
    for n in (0, 3):
        write_result(results, "zero", n, 5.0)
        write_result(results, "zero", n, 5.0, dataset="synthetic-v2")
    write_result(results, "zero", 1, 5.0, dataset="l2l-like")
    long = long_table([results])
    with pytest.raises(ConfigError, match="several datasets"):
        plotting.plot_context_curves(long, ["fd_exp"], tmp_path / "x.png")
    with pytest.raises(ConfigError, match="one context only"):
        plotting.plot_context_curves(long, ["fd_exp"], tmp_path / "x.png", dataset="l2l-like")
    stems = sorted(figure_builders([results]))
    assert stems == ["bars_l2l-like", "bars_synthetic", "bars_synthetic-v2", "context_synthetic",
                     "context_synthetic-v2"]


def test_committed_figures_are_the_set_the_documented_command_writes(monkeypatch):
    # dyadbench plot all results/ --robustness results-robustness --out figures/
    monkeypatch.chdir(REPO)
    expected = figure_files(figure_builders([Path("results")], Path("results-robustness")), ["pdf", "png"])
    committed = sorted(p.name for p in (REPO / "figures").iterdir())
    assert committed == sorted(expected)
    for name in committed:
        assert_opens(REPO / "figures" / name)
