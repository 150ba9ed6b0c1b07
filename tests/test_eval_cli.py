"""``dyadbench eval`` / ``sweep`` / ``models`` / ``datasets`` and the typed result files."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from dyadbench.cli import cli
from dyadbench.errors import ConfigError, InputError
from dyadbench.leaderboard import long_table, wide_table
from dyadbench.protocol.config import ProtocolConfig, variant_label
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.runner import evaluate
from dyadbench.results import load_result, results_frame
from dyadbench.synth.writers import write_dualtalk_split
from tests.protocol_clips import isolated_cache, make_source  # noqa: F401


@pytest.fixture(scope="module")
def dualtalk_dir(tmp_path_factory):
    """A DualTalk-layout folder with 3 train and 3 test dialogues of the synthetic corpus."""
    root = tmp_path_factory.mktemp("dualtalk")
    for split in ("train", "test"):
        write_dualtalk_split(root, split=split, clips=3, seed=0, progress=False)
    return root


def _run(args):
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result


@pytest.mark.parametrize("model", ["random", "lagged-mirror"])
def test_eval_then_score_gives_the_same_numbers(dualtalk_dir, tmp_path, model):
    out = tmp_path / "run"
    _run(["eval", "--model", model, "--data", str(dualtalk_dir), "--split", "test", "--context", "3",
          "--seed", "4", "--out", str(out)])
    result = load_result(out / "result.json")
    assert sorted(p.name for p in (out / "predictions").iterdir()) == sorted(
        f"synth_test_{i:05d}_speaker{k}.npy" for i in range(3) for k in (1, 2))
    pred = np.load(out / "predictions" / "synth_test_00000_speaker1.npy")
    assert pred.dtype == np.float32 and pred.ndim == 2 and pred.shape[1] == 56
    _run(["score", str(out / "predictions"), "--gt", str(dualtalk_dir / "test"), "--seed", "4",
          "--out", str(tmp_path / "scored")])
    scored = json.loads((tmp_path / "scored" / "result.json").read_text())
    assert set(scored["metrics"]) == set(result.metrics)
    for key, value in result.metrics.items():
        np.testing.assert_allclose(scored["metrics"][key], value, rtol=1e-12, atol=1e-15, err_msg=key)
    assert result.model.name == model and result.protocol.context == 3 and result.protocol.seed == 4
    assert result.data.items == 6 and len(result.per_clip) == 6 and (out / "per_clip.csv").is_file()
    assert result.environment["dyadbench"] and result.environment["numpy"] == np.__version__


def test_eval_defaults_to_the_embedded_corpus_and_says_so(dualtalk_dir, tmp_path, monkeypatch):
    import dyadbench.datasets.dualtalk as dualtalk
    import dyadbench.datasets.synthetic as synthetic

    opened = []

    def small_embedded(root, split):
        opened.append((root, split))
        return dualtalk.open_split(dualtalk_dir, split)

    monkeypatch.setattr(synthetic, "open_split_v2", small_embedded)  # corpus v2 is the default
    result = CliRunner().invoke(cli, ["eval", "--model", "mean-frame", "--context", "0", "--clips", "1",
                                      "--out", str(tmp_path / "e")])
    assert result.exit_code == 0, result.output
    assert "using the embedded synthetic-v2 corpus" in result.output
    assert opened[0] == (None, None) and (None, "train") in opened  # no --split: the adapter's default
    recorded = load_result(tmp_path / "e" / "result.json").data
    assert recorded.clips == 1 and recorded.split == "test"


def test_sweep_runs_n_0_3_7_and_adds_rows_without_rerunning(dualtalk_dir, tmp_path):
    out = tmp_path / "results"
    args = ["sweep", "--models", "mean-frame,lagged-mirror", "--splits", "test", "--contexts", "0,3,7",
            "--data", str(dualtalk_dir), "--out", str(out), "--no-per-clip"]
    _run(args)
    files = sorted(out.rglob("*.json"))
    assert [f.relative_to(out).as_posix() for f in files] == [
        f"dualtalk/test/n{n}/{m}.json" for n in (0, 3, 7) for m in ("lagged-mirror", "mean-frame")]
    frame = results_frame([out])
    for model in ("mean-frame", "lagged-mirror"):
        part = frame[frame["model"] == model].pivot_table(index="metric", columns="context", values="raw")
        assert list(part.columns) == [0, 3, 7]
        np.testing.assert_array_equal(part[0], part[3])  # history-free: identical at every n
        np.testing.assert_array_equal(part[0], part[7])
    later = load_result(out / "dualtalk/test/n7/mean-frame.json")
    assert later.per_clip == [] and any("reused" in n for n in later.notes)
    assert later.coverage["scored"] == 6 and all(isinstance(v, int) for v in later.coverage.values())
    again = _run(args + ["--models", "mean-frame,mime"])
    assert again.output.count("skip") == 3
    assert len(list(out.rglob("*.json"))) == 9


def test_sweep_variants_get_their_own_files_and_rows(dualtalk_dir, tmp_path):
    out = tmp_path / "results"
    base = ["sweep", "--models", "random", "--splits", "test", "--contexts", "3", "--data", str(dualtalk_dir),
            "--out", str(out), "--no-per-clip"]
    _run(base)
    seeded = _run(base + ["--seed", "1"])
    assert "skip" not in seeded.output  # the default run's file does not stand in for seed 1
    assert sorted(f.name for f in (out / "dualtalk/test/n3").iterdir()) == ["random.json", "random@seed1.json"]
    default, other = (load_result(out / "dualtalk/test/n3" / name) for name in ("random.json", "random@seed1.json"))
    assert (default.protocol.seed, other.protocol.seed) == (0, 1)
    assert default.metrics["fd_exp"] != other.metrics["fd_exp"]  # random frames: another seed, other numbers
    assert _run(base + ["--seed", "1"]).output.count("skip") == 1
    wide = wide_table(long_table([out]))
    rows = wide.set_index("model")["fd_exp"]
    assert sorted(rows.index) == ["random", "random (seed1)"]
    assert rows["random"] == default.scaled["fd_exp"] and rows["random (seed1)"] == other.scaled["fd_exp"]


def test_variant_label_names_only_non_default_settings():
    assert variant_label() == ""
    assert variant_label(cfg_scale=2.0) == "cfg2"
    assert variant_label(turn_seconds=2.0, tail="pad-last", history_agent="outputs", cfg_scale=1.5,
                         seed=3) == "turn2s+tail-pad-last+history-outputs+cfg1.5+seed3"


def test_parallel_streaming_refuses_unpicklable_options(tmp_path):
    train = make_source(2, split="train", seed=1, seconds=6.0)
    test = make_source(3, seed=2, seconds=6.0)

    def run(jobs):
        return evaluate("random", test, ProtocolConfig(context=2, seed=3), jobs=jobs,
                        options=ModelOptions(train_split=lambda: train), progress=False)

    with pytest.raises(ConfigError, match="picklable"):
        run(2)  # a lambda train split cannot cross processes: refused with a clear message
    assert run(1).metrics["fd_exp"] > 0


def test_parallel_streaming_matches_serial(dualtalk_dir, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    _run(["eval", "--model", "random", "--data", str(dualtalk_dir), "--context", "1", "--out", str(a)])
    _run(["eval", "--model", "random", "--data", str(dualtalk_dir), "--context", "1", "--out", str(b),
          "--jobs", "2"])
    assert load_result(a / "result.json").metrics == load_result(b / "result.json").metrics
    for f in (a / "predictions").iterdir():
        np.testing.assert_array_equal(np.load(f), np.load(b / "predictions" / f.name))


def test_thread_cap_is_recorded_and_does_not_change_predictions(dualtalk_dir, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    _run(["eval", "--model", "random", "--data", str(dualtalk_dir), "--context", "1", "--out", str(a)])
    _run(["eval", "--model", "random", "--data", str(dualtalk_dir), "--context", "1", "--out", str(b),
          "--threads", "1"])
    assert load_result(a / "result.json").timing.threads is None
    assert load_result(b / "result.json").timing.threads == 1
    assert load_result(a / "result.json").metrics == load_result(b / "result.json").metrics
    for f in (a / "predictions").iterdir():
        np.testing.assert_array_equal(np.load(f), np.load(b / "predictions" / f.name))


@pytest.mark.parametrize("args,message", [
    (["eval", "--model", "mean-frme"], "did you mean mean-frame"),
    (["eval", "--model", "zero", "--dataset", "dualtalk"], "needs --data"),
    (["sweep", "--models", "zero", "--contexts", "a,b"], "comma-separated integers"),
])
def test_bad_options_are_explained(args, message):
    result = CliRunner().invoke(cli, args)
    assert result.exit_code != 0
    assert message in str(result.exception) or message in result.output  # ConfigError or click usage error


def test_errors_reach_the_user_as_one_line_without_traceback():
    proc = subprocess.run([sys.executable, "-m", "dyadbench", "eval", "--model", "zero", "--context", "-1"],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "-1" in proc.stderr and "Traceback" not in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "dyadbench", "eval", "--model", "mean-frme"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.startswith("error: unknown model 'mean-frme'")


def test_listing_does_not_import_heavy_modules():
    code = ("import sys; from dyadbench.cli import main\n"
            "for cmd in (['models'], ['datasets']):\n"
            "    try:\n        main(cmd)\n    except SystemExit:\n        pass\n"
            "heavy = [m for m in ('torch', 'sklearn', 'baselines.trivial', 'models.timar') if m in sys.modules]\n"
            "print('HEAVY', heavy)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert "HEAVY []" in proc.stdout, proc.stdout + proc.stderr
    for name in ("mean-frame", "nn-retrieval", "oracle", "timar", "synthetic", "dualtalk"):
        assert name in proc.stdout


# --- result files -------------------------------------------------------------------------------------

@pytest.fixture
def result_file(tmp_path):
    train = make_source(2, split="train", seed=1, seconds=5.0)
    r = evaluate("mean-frame", make_source(2, seed=2, seconds=5.0), ProtocolConfig(context=3),
                 options=ModelOptions(train_split=lambda: train), progress=False)
    return r, r.write(tmp_path / "r.json")


def test_result_round_trip(result_file):
    result, path = result_file
    back = load_result(path)
    assert back.metrics.keys() == result.metrics.keys()
    assert all(back.metrics[k] == v or (np.isnan(v) and np.isnan(back.metrics[k])) for k, v in result.metrics.items())
    assert back.per_clip_frame().shape == result.per_clip_frame().shape
    assert back.model == result.model and back.protocol == result.protocol and back.data == result.data
    frame = results_frame([path])
    assert set(frame["metric"]) == set(result.metrics) and (frame["context"] == 3).all()


@pytest.mark.parametrize("edit,message", [
    (lambda d: d.pop("protocol"), "'protocol' missing"),
    (lambda d: d["protocol"].pop("context"), "lacks context"),
    (lambda d: d["protocol"].update(context="7"), "protocol.context has the wrong type"),
    (lambda d: d["model"].update(oracle=1), "model.oracle has the wrong type"),
    (lambda d: d["metrics"].update(fd_exp="big"), "metrics.fd_exp is not a number"),
    (lambda d: d.update(schema="other/1"), "not a dyadbench eval result"),
    (lambda d: d["per_clip"]["rows"][0].pop(), "per_clip row 0"),
])
def test_malformed_result_files_are_rejected_by_name(result_file, edit, message):
    _, path = result_file
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=message) as exc:
        load_result(path)
    assert str(path) in str(exc.value)


def test_unreadable_result_files_are_rejected(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not readable JSON"):
        results_frame([tmp_path])
    with pytest.raises(InputError, match="no such result"):
        results_frame([tmp_path / "missing"])


def test_single_participant_gaze_sessions_are_scored_with_the_gaze_suite():
    from dyadbench.datasets.base import InMemorySource
    from dyadbench.synth.gaze import make_gaze_sessions

    train = InMemorySource(make_gaze_sessions("train", 2, duration_s=12.0), "gaze-small", "train")
    test = InMemorySource(make_gaze_sessions("test", 2, duration_s=12.0), "gaze-small", "test")
    scores = {m: evaluate(m, test, ProtocolConfig(context=3), options=ModelOptions(train_split=lambda: train),
                          progress=False) for m in ("mean-frame", "oracle")}
    assert {r.suite for r in scores.values()} == {"gaze"}
    assert scores["oracle"].model.oracle and scores["oracle"].data.items == 2
    assert scores["oracle"].metrics["mae_all"] == 0.0 < scores["mean-frame"].metrics["mae_all"]


def test_device_reaches_the_model_and_the_result_and_a_missing_device_is_refused(dualtalk_dir, tmp_path):
    """--device is handed to the model (ModelOptions.device) and recorded; a device this machine lacks, or a
    name torch does not know, is a usage error (exit 2) that names the value, never a traceback."""
    out = tmp_path / "run"
    _run(["eval", "--model", "dualtalk", "--data", str(dualtalk_dir), "--split", "test", "--context", "1",
          "--clips", "1", "--device", "cpu", "--out", str(out)])
    assert load_result(out / "result.json").environment["device"] == "cpu"
    for bad in ("gpu0", "cuda:99" if __import__("torch").cuda.is_available() else "cuda"):
        result = CliRunner().invoke(cli, ["eval", "--model", "zero", "--data", str(dualtalk_dir), "--split",
                                          "test", "--device", bad, "--out", str(tmp_path / "x")])
        assert result.exit_code == 2 and bad in result.output and "Traceback" not in result.output
        assert not (tmp_path / "x").exists()


def test_eval_without_out_keeps_a_variant_beside_the_plain_run(dualtalk_dir, tmp_path, monkeypatch):
    """The default output folder names the run's variant, so a perturbed (or guided) run never replaces the
    clean run's folder."""
    monkeypatch.chdir(tmp_path)
    base = ["eval", "--model", "zero", "--data", str(dualtalk_dir), "--split", "test", "--context", "1"]
    _run(base)
    _run(base + ["--perturb", "partner-motion:drop:0.3"])
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [
        "zero_dualtalk_test_n1", "zero_dualtalk_test_n1@partner-motion-drop0.3"]
