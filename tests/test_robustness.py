"""The robustness axis on the command line: perturbed runs get their own result files and skip logic, the
sweep writes a degradation table and plot that regenerate byte for byte, and leaderboards leave them out."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dyadbench.results import load_result, results_frame
from dyadbench.robustness import AGENT_SILENCED, FAMILIES, sweep_settings
from tests.hostile_cli import dyadbench, error_line, write_root
from tests.protocol_clips import isolated_cache  # noqa: F401

TABLES = ("robustness.csv", "robustness.md", "robustness.tex", "robustness.png")


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return write_root(tmp_path_factory.mktemp("dualtalk"), train=2, test=2)


def _ok(capsys, *args) -> str:
    code, output = dyadbench(capsys, *args)
    assert code == 0 and "Traceback" not in output, output
    return output


def test_sweep_settings_are_the_papers():
    settings = sweep_settings()
    assert settings[0] == () and settings[-1] == (AGENT_SILENCED,) and len(settings) == 2 + 4 * len(FAMILIES)
    assert {p.occupancy for (p,) in settings[1:-1]} == {0.1, 0.3, 0.5, 0.7}
    assert {p.burst_s for (p,) in settings[1:-1]} == {1.0} and AGENT_SILENCED.text() == "agent-speech:silence:1:4"


def test_perturbed_sweep_runs_have_their_own_files_and_skip_logic(root, tmp_path, capsys):
    args = ["sweep", "--models", "mime", "--splits", "test", "--contexts", "1", "--out", tmp_path, "--data", root]
    _ok(capsys, *args)
    _ok(capsys, *args, "--perturb", "partner-motion:drop:0.3")
    folder = tmp_path / "dualtalk" / "test" / "n1"
    clean, dropped = folder / "mime.json", folder / "mime@partner-motion-drop0.3.json"
    assert load_result(clean).metrics != load_result(dropped).metrics
    assert "skip" in _ok(capsys, *args, "--perturb", "partner-motion:drop:0.3")
    _ok(capsys, *args, "--perturb", "partner-motion:gaussian:0.3", "--noise-scale", "0.2")
    assert (folder / "mime@partner-motion-gaussian0.3+sigma0.2.json").is_file()
    assert list(results_frame([tmp_path])["file"].unique()) == [str(clean)]  # leaderboards leave perturbed runs out


def test_robustness_command_table_regenerates_byte_for_byte(root, tmp_path, capsys):
    results, first, second = tmp_path / "results", tmp_path / "first", tmp_path / "second"
    _ok(capsys, "robustness", "--models", "zero,mime", "--levels", "0.5", "--data", root, "--threads", "1",
        "--results", results, "--out", first)
    _ok(capsys, "robustness", "--table-only", "--results", results, "--out", second)
    for name in TABLES:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    rows = (first / "robustness.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * (len(FAMILIES) + 1) * 9  # 2 models x (6 families at 0.5 + silenced) x 9 metrics
    folder = results / "dualtalk" / "test" / "n7"
    clean, noisy = load_result(folder / "mime.json"), load_result(folder / "mime@partner-motion-gaussian0.5.json")
    row = next(r for r in rows if r.startswith("mime,") and ",partner-motion gaussian,0.5,1,mse_jaw," in r)
    assert float(row.split(",")[11]) == pytest.approx(noisy.metrics["mse_jaw"] - clean.metrics["mse_jaw"])
    zero = [r.split(",") for r in rows[1:] if r.startswith("zero,")]
    assert {float(r[11]) for r in zero} == {0.0}  # zero reads no input: no degradation
    assert json.loads(json.dumps(noisy.configuration))["noise_scale"] == noisy.protocol.noise_scale


def test_bad_perturbation_is_a_usage_error(root, capsys):
    code, output = dyadbench(capsys, "eval", "--model", "zero", "--data", root, "--perturb", "partner-motion:hum:0.3")
    assert code == 2 and "partner-motion perturbations are drop, gaussian, laplace, uniform" in output
    code, output = dyadbench(capsys, "eval", "--model", "zero", "--data", root / "test", "--perturb",
                             "partner-motion:gaussian:0.3", "--out", root.parent / "never")
    assert code == 2 and "--noise-scale" in error_line(output)


def test_committed_table_and_plot_regenerate_from_the_committed_results(tmp_path, capsys, monkeypatch):
    repo = Path(__file__).resolve().parents[1]
    monkeypatch.chdir(repo)  # the table records the result files' paths as given
    _ok(capsys, "robustness", "--table-only", "--results", "results-robustness", "--out", tmp_path)
    for name in TABLES:
        assert (tmp_path / name).read_bytes() == (repo / "leaderboards" / name).read_bytes(), name
