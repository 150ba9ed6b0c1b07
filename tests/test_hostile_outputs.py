"""Output folders owned by one run, output paths checked before any work, finished results never lost.

Every case runs the real command line (``dyadbench.cli.main``, or ``python -m dyadbench`` for the SIGINT
case) on a DualTalk-layout root of 2 train and 6 test dialogues.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from dyadbench import outputs
from dyadbench.results import EvalResult, load_result, result_files
from dyadbench.synth.writers import write_dualtalk_split
from tests.hostile_cli import dyadbench, error_line

EVAL = ("eval", "--model", "mean-frame", "--split", "test", "--context", "1")


@pytest.fixture(autouse=True)
def isolated_cache(tmp_path_factory, monkeypatch):
    """A per-session cache (also seen by the subprocess), never the user's."""
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path_factory.getbasetemp() / "dyadbench-cache"))


@pytest.fixture(scope="module")
def data_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("dualtalk")
    write_dualtalk_split(root, split="train", clips=2, seed=0, progress=False)
    write_dualtalk_split(root, split="test", clips=6, seed=0, progress=False)
    return root


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (hidden ones too) by relative path, with its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def stems(run: Path) -> list[str]:
    return sorted(p.name for p in (run / "predictions").iterdir())


def expected_stems(clips: int) -> list[str]:
    return sorted(f"synth_test_{i:05d}_speaker{k}.npy" for i in range(clips) for k in (1, 2))


# --- eval --out is owned by one run -------------------------------------------------------------------

def test_sigint_during_eval_leaves_the_previous_run_byte_identical(data_root, tmp_path, capsys):
    out = tmp_path / "run"
    code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 2, "--out", out)
    assert code == 0, text
    before = snapshot(out)
    assert "result.json" in before and len([k for k in before if k.startswith("predictions/")]) == 4

    # all 6 clips, 1-frame turns: the run lasts well beyond the first prediction file. SIGINT's default
    # action is restored in the child: a test run started in the background of a shell (CI scripts)
    # inherits "ignore SIGINT", and Python then never installs its KeyboardInterrupt handler
    proc = subprocess.Popen([sys.executable, "-m", "dyadbench", *EVAL, "--data", str(data_root),
                             "--turn-seconds", "0.04", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    written = []
    while not written and proc.poll() is None and time.monotonic() < deadline:
        written = list(tmp_path.glob(f".run{outputs.STAGING}*/predictions/*.npy"))
        time.sleep(0.005)
    assert written, "the second run ended before writing a prediction into its temporary folder"
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout + stderr
    assert "Aborted." in stderr and "Traceback" not in stderr
    assert snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no temporary folder left


def test_a_smaller_rerun_leaves_only_its_own_files_and_score_scores_exactly_them(data_root, tmp_path, capsys):
    out = tmp_path / "run"
    assert dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 3, "--out", out)[0] == 0
    assert stems(out) == expected_stems(3)
    code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out)
    assert code == 0, text
    assert stems(out) == expected_stems(1)
    result = load_result(out / "result.json")
    assert result.data.clips == 1 and result.data.items == 2 and result.predictions == str(out / "predictions")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert result_files([out]) == [out / "result.json"]  # the folder's marker is no result file for leaderboards

    code, text = dyadbench(capsys, "score", out / "predictions", "--gt", data_root / "test", "--out", tmp_path / "s")
    assert code == 0, text
    scored = json.loads((tmp_path / "s" / "result.json").read_text())
    assert scored["data"]["items"] == 2 and "scored 2 of 12" in text  # 6 dialogues in the split, clip 0 predicted
    rows = (tmp_path / "s" / "per_clip.csv").read_text().splitlines()[1:]
    assert [row.split(",")[0] for row in rows] == ["synth_test_00000_speaker1", "synth_test_00000_speaker2"]


def test_an_output_written_before_the_marker_existed_is_replaced(data_root, tmp_path, capsys):
    out = tmp_path / "run"
    assert dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 2, "--out", out)[0] == 0
    (out / outputs.MARKER).unlink()  # as an older dyadbench left it: recognised by its result.json
    assert dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out)[0] == 0
    assert stems(out) == expected_stems(1)


def test_eval_refuses_a_foreign_folder_and_force_replaces_it(data_root, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me\n")
    code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out)
    assert code == 2
    line = error_line(text)
    assert str(out) in line and "--force" in line
    assert snapshot(out) == {"notes.txt": b"keep me\n"} and [p.name for p in tmp_path.iterdir()] == ["mine"]

    code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out, "--force")
    assert code == 0, text
    assert not (out / "notes.txt").exists() and stems(out) == expected_stems(1)


def test_sweep_keeps_each_runs_predictions_from_that_run_only(data_root, tmp_path, capsys):
    args = ("sweep", "--models", "zero", "--data", data_root, "--splits", "test", "--contexts", 0,
            "--out", tmp_path / "results", "--keep-predictions", tmp_path / "kept")
    assert dyadbench(capsys, *args, "--clips", 3)[0] == 0
    assert dyadbench(capsys, *args, "--clips", 1, "--force")[0] == 0
    run = tmp_path / "kept" / "dualtalk" / "test" / "n0" / "zero"
    assert sorted(p.name for p in run.glob("*.npy")) == expected_stems(1)
    assert sorted(p.name for p in run.parent.iterdir()) == ["zero"]
    assert load_result(tmp_path / "results" / "dualtalk" / "test" / "n0" / "zero.json").predictions == str(run)


# --- data synth replaces a split whole ----------------------------------------------------------------

SYNTH = [("dualtalk", "test", 3, 2), ("react", "test", 2, 1), ("l2l", "test", 3, 2), ("gaze", "val", 2, 1)]


@pytest.mark.parametrize("layout,split,first,second", SYNTH, ids=[s[0] for s in SYNTH])
def test_synth_over_a_generated_split_equals_a_fresh_one(tmp_path, capsys, layout, split, first, second):
    def synth(root: Path, clips: int) -> None:
        code, text = dyadbench(capsys, "data", "synth", "--out", root, "--layout", layout, "--split", split,
                               "--clips", clips)
        assert code == 0, text

    synth(tmp_path / "reused", first)
    synth(tmp_path / "reused", second)
    synth(tmp_path / "fresh", second)
    assert snapshot(tmp_path / "reused") == snapshot(tmp_path / "fresh")  # no clip of the first run left
    code, text = dyadbench(capsys, "data", "validate", "--layout", layout, tmp_path / "reused")
    assert code == 0 and "0 errors" in text


def test_synth_refuses_a_split_folder_holding_other_files_and_validate_agrees(tmp_path, capsys):
    stale = tmp_path / "root" / "test"
    write_dualtalk_split(tmp_path / "old", split="test", clips=3, seed=5, progress=False)
    shutil.copytree(tmp_path / "old" / "test", stale)
    (stale / "synthetic.json").unlink()  # hand-placed clips, not a generated split
    (stale / outputs.MARKER).unlink()
    before = snapshot(stale)
    code, text = dyadbench(capsys, "data", "synth", "--out", tmp_path / "root", "--clips", 2)
    assert code == 2
    line = error_line(text)
    assert str(stale) in line and "--force" in line
    assert snapshot(stale) == before and sorted(p.name for p in stale.parent.iterdir()) == ["test"]

    assert dyadbench(capsys, "data", "synth", "--out", tmp_path / "root", "--clips", 2, "--force")[0] == 0
    assert len(list(stale.glob("*.npz"))) == 4
    code, text = dyadbench(capsys, "data", "validate", stale)
    assert code == 0 and "2 checked, 0 errors" in text


# --- output paths are checked before any work -----------------------------------------------------------

def _boom(*args, **kwargs):
    raise AssertionError("work started before the output path was checked")


#: every way a command starts work: opening a dataset, building a model, scoring, reading results, generating
WORK = ["dyadbench.registry.DATASETS.load", "dyadbench.registry.MODELS.load", "dyadbench.registry.SUITES.load",
        "dyadbench.cli.leaderboard.long_table", "dyadbench.results.results_frame",
        "dyadbench.synth.writers.make_clip"]


#: command line per case; {bad} is the unusable output path, {root} the data root
UNDER_A_FILE = {
    "eval": [*EVAL, "--data", "{root}", "--out", "{bad}"],
    "sweep": ["sweep", "--models", "zero", "--data", "{root}", "--splits", "test", "--contexts", "0", "--out", "{bad}"],
    "sweep-keep": ["sweep", "--models", "zero", "--data", "{root}", "--splits", "test", "--contexts", "0",
                   "--out", "{root}/../results", "--keep-predictions", "{bad}"],
    "score": ["score", "{root}/test", "--gt", "{root}/test", "--out", "{bad}"],
    "leaderboard": ["leaderboard", "{root}", "--out", "{bad}"],
    "plot-context": ["plot", "context", "{root}", "--out", "{bad}/p.png"],
    "plot-trajectories": ["plot", "trajectories", "{root}/test", "--clip", "synth_test_00000", "--data", "{root}",
                          "--out", "{bad}/p.png"],
    "synth": ["data", "synth", "--out", "{bad}", "--clips", "1"],
    "train-timar": ["train", "timar", "--data", "{root}", "--out", "{bad}"],
}


def _check_refused(capsys, args: list[str], root: Path, bad: str, *expected: str) -> None:
    """The command (``bad`` as its output path) exits 2 with one error line holding every ``expected`` text."""
    code, text = dyadbench(capsys, *[a.format(root=root, bad=bad) for a in args])
    assert code == 2
    line = error_line(text)
    assert all(e in line for e in expected), line


@pytest.mark.parametrize("case", list(UNDER_A_FILE))
def test_an_output_under_a_file_fails_before_any_work(data_root, tmp_path, capsys, monkeypatch, case):
    for target in WORK:
        monkeypatch.setattr(target, _boom)
    (tmp_path / "file").write_text("not a folder\n")
    bad = str(tmp_path / "file" / "out")
    _check_refused(capsys, UNDER_A_FILE[case], data_root, bad, bad, f"{tmp_path / 'file'} exists and is not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


@pytest.mark.parametrize("case", ["eval", "synth"])
def test_an_over_long_output_name_fails_before_any_work(data_root, tmp_path, capsys, monkeypatch, case):
    for target in WORK:
        monkeypatch.setattr(target, _boom)
    bad = str(tmp_path / ("x" * 300))
    _check_refused(capsys, UNDER_A_FILE[case], data_root, bad, bad, "(File name too long)")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("case", ["eval", "sweep", "plot-trajectories", "train-timar"])
def test_a_cache_that_is_a_file_fails_before_any_work(data_root, tmp_path, capsys, monkeypatch, case):
    for target in WORK:
        monkeypatch.setattr(target, _boom)
    cache = tmp_path / "cache"
    cache.write_text("not a folder\n")
    monkeypatch.setenv("DYADBENCH_CACHE", str(cache))
    _check_refused(capsys, UNDER_A_FILE[case], data_root, str(tmp_path / "out"),
                   f"DYADBENCH_CACHE={cache}: {cache} exists and is not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache"]


def _refuse_writes_below(folder: Path, monkeypatch) -> None:
    """Make creating a folder or a file below ``folder`` fail with EACCES, as a read-only folder does."""
    mkdir, mkstemp = os.mkdir, tempfile.mkstemp

    def refused(path) -> bool:
        return Path(path).is_relative_to(folder)

    def guarded_mkdir(path, *args, **kwargs):
        if refused(path):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return mkdir(path, *args, **kwargs)

    def guarded_mkstemp(*args, dir=None, **kwargs):
        if dir is not None and refused(dir):
            raise PermissionError(errno.EACCES, "Permission denied", str(dir))
        return mkstemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(os, "mkdir", guarded_mkdir)
    monkeypatch.setattr(tempfile, "mkstemp", guarded_mkstemp)


def test_a_read_only_output_folder_fails_before_any_work(data_root, tmp_path, capsys, monkeypatch):
    for target in WORK:
        monkeypatch.setattr(target, _boom)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    if os.geteuid() == 0:  # root writes into read-only folders: the file system's refusal is simulated
        _refuse_writes_below(locked, monkeypatch)
    try:
        bad = str(locked / "run")
        _check_refused(capsys, UNDER_A_FILE["eval"], data_root, bad, bad, "Permission denied")
    finally:
        locked.chmod(0o755)
    assert list(locked.iterdir()) == []


# --- a failure to write after the work keeps the result -------------------------------------------------

def test_a_result_that_cannot_be_written_is_kept_and_named(data_root, tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    assert dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out)[0] == 0
    before = snapshot(out)

    def disk_full(self, path):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(EvalResult, "write", disk_full)
    code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 2, "--out", out)
    assert code == 2
    line = error_line(text)
    assert f"{out / 'result.json'}: could not write it (No space left on device)" in line
    kept = Path(line.split("the computed result is kept in ")[1])
    try:
        assert load_result(kept).data.clips == 2
    finally:
        kept.unlink()
    assert snapshot(out) == before and [p.name for p in tmp_path.iterdir()] == ["run"]


def test_a_finished_output_that_cannot_be_moved_in_is_kept_whole(data_root, tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    assert dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 1, "--out", out)[0] == 0
    before = snapshot(out)
    rename = os.rename

    def refuse_staging(src, dst):
        if outputs.STAGING in os.fspath(src):
            raise OSError(errno.EXDEV, "Invalid cross-device link")
        return rename(src, dst)

    with monkeypatch.context() as patched:
        patched.setattr(os, "rename", refuse_staging)
        code, text = dyadbench(capsys, *EVAL, "--data", data_root, "--clips", 2, "--out", out)
    assert code == 2
    line = error_line(text)
    assert f"--out {out}: could not move the finished output into place" in line
    staging = Path(line.split("it is complete in ")[1])
    assert staging.parent == tmp_path and stems(staging) == expected_stems(2)
    assert load_result(staging / "result.json").data.clips == 2
    assert snapshot(out) == before  # the previous output was put back
