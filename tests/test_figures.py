"""Figures: format by extension (PDF/SVG/PNG, others refused), one style per model in every figure, baselines
secondary, variants as their own series, distinct series within a figure, trivial baselines off-scale, axes at
the protocol's values, datasets never mixed, and the committed figure set."""

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
from dyadbench.figure_range import value_range
from dyadbench.figure_set import figure_builders, figure_files, figure_metrics
from dyadbench.leaderboard import long_table
from dyadbench.registry import MODELS
from dyadbench.robustness import degradation_frame
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


def test_models_have_their_own_colours_and_baselines_are_grey_and_thin():
    tags = {name: MODELS.get(name).tags for name in MODELS.names()}
    models = [n for n, t in tags.items() if "baseline" not in t and "oracle" not in t]
    baselines = [n for n, t in tags.items() if "baseline" in t]
    assert {"timar", "timar-stream", "dualtalk", "dualtalk-offline", "sfms", "stygazetalk"} <= set(models)
    assert {"zero", "mean-frame", "random", "mime", "nn-retrieval", "gaze-static"} <= set(baselines)
    styles = {n: figure_style.model_style(n) for n in models + baselines}
    assert len({styles[m].color for m in models}) == len(models)  # no two models share a colour
    greys = {"#9A9A9A", "#5E5E5E"}
    for m in models:
        assert styles[m].color not in greys | {"#000000"} and styles[m].linewidth == 1.3, m
    for b in baselines:
        assert styles[b].color in greys and styles[b].linewidth == 0.8, b
        assert styles[b].marker not in {styles[m].marker for m in models}, b  # markers unlike any model's
    assert len({(s.color, s.marker) for s in styles.values()}) == len(styles)
    for oracle in ("oracle", "gaze-headcopy"):
        assert (figure_style.model_style(oracle).color, figure_style.model_style(oracle).linestyle) == ("#000000",
                                                                                                      "--")


def test_unknown_names_get_a_fixed_style_and_a_figure_never_repeats_one():
    names = [f"model-{i}" for i in range(30)]
    assert [figure_style.model_style(n) for n in names] == [figure_style.model_style(n) for n in names]
    assert all(figure_style.model_style(n).kind == "model" for n in names)
    # 10 models in one figure (6 reference + 4 new names): 10 colours; 30 new names: no style twice
    few = figure_styles_of(["timar", "timar-stream", "dualtalk", "dualtalk-offline", "sfms", "stygazetalk",
                            *names[:4], "zero", "oracle"])
    colours = [few[n].color for n in few if few[n].kind == "model"]
    assert len(colours) == len(set(colours)) == 10
    assert few["timar"] == figure_style.model_style("timar")  # registered names never move
    many = figure_styles_of([*names, "zero", "random", "timar", "timar (cfg1.5)", "timar (cfg2)", "timar (cfg3)",
                             "timar (cfg4)"])
    triples = [(s.color, s.marker, s.linestyle) for s in many.values()]
    assert len(set(triples)) == len(triples) == len(many)
    assert {many[f"timar (cfg{k})"].color for k in ("1.5", 2, 3, 4)} == {many["timar"].color}


def figure_styles_of(labels: list[str]) -> dict[str, figure_style.SeriesStyle]:
    return figure_style.figure_styles((label, label == "oracle") for label in labels)


def test_committed_result_set_has_distinct_series_in_every_figure(monkeypatch):
    monkeypatch.chdir(REPO)
    long = long_table([Path("results")])
    figures = {}
    for dataset in sorted(set(long["dataset"])):
        rows = long[long["dataset"] == dataset]
        metrics = [m for m in figure_metrics(rows["suite"].iloc[0]) if m in set(rows["metric"])]
        figures[dataset] = plotting.series_of(plotting.labelled(rows, dataset, metrics))
    frame, _ = degradation_frame([Path("results-robustness")])
    figures["robustness"] = [(model, False) for model in set(frame["model"])]
    assert {"synthetic", "l2l", "synthetic-gaze", "robustness"} <= set(figures)
    for name, series in figures.items():
        styles = figure_style.figure_styles(series)
        triples = [(s.color, s.marker, s.linestyle) for s in styles.values()]
        assert len(set(triples)) == len(triples), name
        models = {figure_style.split_label(label)[0]: s.color for label, s in styles.items() if s.kind == "model"}
        assert len(set(models.values())) == len(models), name
    assert len([s for s in figure_style.figure_styles(figures["synthetic"]).values() if s.kind == "model"]) == 7


def test_baselines_far_from_the_models_go_off_scale():
    # models 0 (oracle), 4, 10: reach 10, so a baseline beyond 10 + 10 = 20 is off-scale; 18 stays
    scale = value_range({"oracle": [0.0], "timar": [4.0, 5.0], "dualtalk": [10.0], "zero": [65.3, 65.3],
                         "mean-frame": [18.0], "random": [float("nan"), 20.0]}, {"zero", "mean-frame", "random"})
    assert (scale.low, scale.high, scale.above, scale.below) == (0.0, 20.0, {"zero": 65.3}, {})
    assert scale.limits() == pytest.approx((-0.05 * 20, 20 + 0.16 * 20))
    # a tight cluster far from 0 (0.61..0.77): reach is its magnitude 0.77, so a baseline at 0.28 stays
    assert value_range({"m": [0.61, 0.77], "b": [0.28]}, {"b"}).below == {}
    # below: models 10..12 reach 12, a baseline at -5 < 10 - 12; a model far away is never off-scale
    scale = value_range({"m": [10.0, 12.0], "b": [-5.0]}, {"b"})
    assert (scale.low, scale.high, scale.above, scale.below) == (10.0, 12.0, {}, {"b": -5.0})
    assert scale.limits() == pytest.approx((10 - 0.16 * 2, 12 + 0.05 * 2))
    scale = value_range({"m": [10.0, 12.0], "other": [100.0]}, set())
    assert (scale.low, scale.high, scale.above) == (10.0, 100.0, {})
    assert value_range({"b": [1.0], "c": [1000.0]}, {"b", "c"}).above == {}  # no model: nothing off-scale
    with pytest.raises(ValueError, match="no finite value"):
        value_range({"m": [float("nan")]}, set())


def test_context_curves_draw_an_off_scale_baseline_at_the_edge_with_its_value(tmp_path, captured):
    results = tmp_path / "r"
    for n in (0, 7):
        write_result(results, "zero", n, 65.3)
        write_result(results, "timar", n, 5.0 + n / 7)
        write_result(results, "oracle", n, 0.0, oracle=True)
    plotting.plot_context_curves(long_table([results]), ["fd_exp"], tmp_path / "c.png")
    (ax,) = captured[0].axes
    low, high = ax.get_ylim()
    assert (low, high) == pytest.approx((-0.05 * 6, 6 + 0.16 * 6))  # kept: 0..6
    zero = next(line for line in ax.get_lines() if line.get_label() == "zero")
    assert list(zero.get_ydata()) == pytest.approx([high, high])
    assert [t.get_text() for t in ax.texts] == ["zero 65.3 ↑"]
    assert legend(captured[0])["zero"][0] == "#9A9A9A"


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
