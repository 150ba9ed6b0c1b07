"""One bad-input policy for every metric suite (:mod:`dyadbench.scoring.policy`), through the real CLI.

The same bad input is given to every suite (dualtalk, react, l2l, gaze) via ``dyadbench score --strict
--out``; each case has one outcome class whatever the suite: the prediction is *excluded* and listed
(``--strict`` exits 1), it is *missing* (exit 1) or *extra* (exit 0), a *warning* names the file (exit 0),
or an *error* names the file (exit 2, nothing written, the previous results byte-identical). Never a
traceback. Errors raised in worker processes reach the user as the same line with ``--jobs 2`` as with
``--jobs 1``, for ``score`` and for ``eval``.
"""

from __future__ import annotations

import json
import os
import pickle
import threading
import re
import shutil
import zipfile
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from dyadbench.cli import main
from dyadbench.datasets import gaze as gaze_layout
from dyadbench.datasets import l2l as l2l_layout
from dyadbench.datasets.dualtalk_files import load_gt_npz
from dyadbench.datasets.react import ReactSplit
from dyadbench.errors import ConfigError, InputError, OutputError
from dyadbench.metrics.react import FRAMES, REACTIONS
from dyadbench.workers import process_map
from tests.hostile_cli import run_cli

SUITES = ("dualtalk", "react", "l2l", "gaze")
CLIPS = {"dualtalk": 2, "react": 1, "l2l": 1, "gaze": 2}


@dataclass(frozen=True)
class Corpus:
    """One suite's tiny ground truth and a complete prediction set (equal to the ground truth)."""

    suite: str
    gt: Path  # what --gt gets
    pred: Path  # the prediction folder
    pred_file: Path  # the first prediction (sorted)
    gt_file: Path  # a ground-truth motion file

    @property
    def stem(self) -> str:
        """The first prediction's name (its path under the folder, without .npy)."""
        return self.pred_file.relative_to(self.pred).with_suffix("").as_posix()

    def moved(self, old: Path, new: Path) -> Corpus:
        return Corpus(self.suite, *(new / p.relative_to(old) for p in (self.gt, self.pred, self.pred_file,
                                                                       self.gt_file)))


def dyadbench(capsys, *args) -> tuple[int, str, str]:
    """``dyadbench ARGS`` through its entry point: (exit status, stdout, stderr), never a traceback."""
    code, out, err = run_cli(capsys, *args)
    assert "Traceback" not in out + err
    return code, out, err


def error_lines(text: str) -> list[str]:
    """The ``error: ...`` messages of a command's output (progress bars may share their line)."""
    return re.findall(r"error: [^\r\n]*", text)


def _predictions(suite: str, gt: Path, pred: Path) -> None:
    """A prediction equal to the ground truth for every item of ``gt``."""
    if suite == "dualtalk":
        for f in sorted(gt.glob("*.npz")):
            np.save(pred / f"{f.stem}.npy", load_gt_npz(f).astype(np.float32))
    elif suite == "react":
        data = ReactSplit.open(gt, "test")
        emotions = data.emotions(FRAMES)
        for speaker, listener in data.samples:
            (pred / speaker).parent.mkdir(parents=True, exist_ok=True)
            np.save(pred / f"{speaker}.npy", np.repeat(emotions[listener][None], REACTIONS, axis=0))
    elif suite == "l2l":
        stems, listener, _ = l2l_layout.ground_truth(gt, "test")
        for stem, motion in zip(stems, listener):
            np.save(pred / f"{stem}.npy", motion.astype(np.float32))
    else:
        for clip in gaze_layout.open_split(gt, "test"):
            np.save(pred / f"{clip.clip_id}_subject.npy", clip.participants[0].motion)


def _ground_truth_file(suite: str, gt: Path) -> Path:
    return {"dualtalk": lambda: sorted(gt.glob("*.npz"))[0],
            "react": lambda: sorted((gt / "test" / "Emotion").rglob("*.csv"))[0],
            "l2l": lambda: gt / "synth" / "test" / l2l_layout.array_name(0, "list_faces"),
            "gaze": lambda: sorted((gt / "test").glob("*.npz"))[0]}[suite]()


@pytest.fixture(scope="module")
def corpora(tmp_path_factory) -> dict[str, Corpus]:
    """Per suite: ground truth from ``dyadbench data synth`` (1-2 dialogues) and predictions equal to it."""
    base = tmp_path_factory.mktemp("hostile-inputs")
    out = {}
    for suite in SUITES:
        root = base / suite / "gt"
        try:
            main(["data", "synth", "--layout", suite, "--out", str(root), "--split", "test",
                  "--clips", str(CLIPS[suite])])
        except SystemExit as exc:
            assert exc.code == 0
        gt = root / "test" if suite == "dualtalk" else root
        pred = base / suite / "pred"
        pred.mkdir()
        _predictions(suite, gt, pred)
        out[suite] = Corpus(suite, gt, pred, sorted(pred.rglob("*.npy"))[0], _ground_truth_file(suite, gt))
    return out


@pytest.fixture(scope="module")
def good_results(corpora, tmp_path_factory) -> dict[str, Path]:
    """Per suite: the results folder of scoring the clean predictions (the 'previous good output')."""
    base = tmp_path_factory.mktemp("good-results")
    folders = {}
    for suite, c in corpora.items():
        folders[suite] = base / suite
        try:
            main(["score", str(c.pred), "--gt", str(c.gt), "--suite", suite, "--strict", "--out", str(folders[suite])])
        except SystemExit as exc:
            assert exc.code == 0
    return folders


def _edit_ground_truth(c: Corpus, change) -> None:
    """Rewrite the motion array of ``c.gt_file`` as ``change(array)``, in the layout's own format."""
    if c.suite == "react":
        table = pd.read_csv(c.gt_file)
        values = change(table.to_numpy())
        pd.DataFrame(values, columns=table.columns if values.shape[1] == table.shape[1] else None).to_csv(
            c.gt_file, index=False)
    elif c.suite == "l2l":
        np.save(c.gt_file, change(np.load(c.gt_file)))
    else:
        key = "exp" if c.suite == "dualtalk" else "motion"
        arrays = dict(np.load(c.gt_file))
        arrays[key] = change(arrays[key])
        np.savez(c.gt_file, **arrays)


def _with_value(value: float):
    def change(array: np.ndarray) -> np.ndarray:
        array = np.array(array, dtype=np.float64, order="C")  # a pandas table's values may be F-ordered
        array.reshape(-1)[7] = value
        return array
    return change


def _transposed(array: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.swapaxes(array, -1, -2))


def _nan_prediction(c: Corpus) -> None:
    np.save(c.pred_file, _with_value(np.nan)(np.load(c.pred_file)).astype(np.float32))


def _int_prediction(c: Corpus) -> None:
    np.save(c.pred_file, np.load(c.pred_file).astype(np.int64))


def _extra_prediction(c: Corpus) -> None:
    shutil.copy(c.pred_file, c.pred / "zz_extra.npy")


def _random_bytes(c: Corpus) -> None:
    c.pred_file.write_bytes(np.random.default_rng(0).bytes(300))


def _folder_for_a_file(c: Corpus) -> None:
    c.pred_file.unlink()
    c.pred_file.mkdir()


def _symlink_loop(c: Corpus) -> None:
    c.pred_file.unlink()
    os.symlink(c.pred_file.name, c.pred_file)


def _duplicate_key(c: Corpus) -> Path:
    """An .npz of every prediction, the first one stored twice under the same name."""
    archive = c.pred.parent / "preds.npz"
    files = sorted(c.pred.rglob("*.npy"))
    with pytest.warns(UserWarning, match="Duplicate name"), zipfile.ZipFile(archive, "w") as z:
        for f in files + files[:1]:
            z.write(f, f.relative_to(c.pred).as_posix())
    return archive


# case -> (make it; outcome class; which file the message names; what it says)
CASES = {
    "NaN prediction": (_nan_prediction, "excluded", "pred_file", "1 NaN/inf values"),
    "int dtype prediction": (_int_prediction, "error", "pred_file", "expected real floating-point values, got dtype "
                                                                     "int64"),
    "extra prediction": (_extra_prediction, "extra", None, "without ground truth"),
    "missing prediction": (lambda c: c.pred_file.unlink(), "missing", None, None),
    "duplicate npz key": (_duplicate_key, "error", "archive", "duplicate zip members"),
    "NaN in ground truth": (lambda c: _edit_ground_truth(c, _with_value(np.nan)), "error", "gt_file",
                            "contains 1 NaN/inf values"),
    "1e30 in ground truth": (lambda c: _edit_ground_truth(c, _with_value(1e30)), "warning", "gt_file",
                             "values up to 1e+30 in magnitude"),
    "random bytes": (_random_bytes, "error", "pred_file", "not a NumPy .npy/.npz file"),
    "transposed ground truth": (lambda c: _edit_ground_truth(c, _transposed), "error", "gt_file", "looks transposed"),
    "folder where a file is expected": (_folder_for_a_file, "error", "pred_file", "is a folder, expected a file"),
    "symbolic link loop": (_symlink_loop, "error", "pred_file", "symbolic link loop"),
}
STRICT_EXIT = {"excluded": 1, "missing": 1, "extra": 0, "warning": 0, "error": 2}
# A warning never fails --strict by itself; but 1e30 can leave a clip unscorable (DualTalk's P-FD of its
# partner: excluded with the reason) and the gaze layout drops frames beyond 40° (the session's clip is
# renamed, so its prediction is missing): then --strict fails for that reason, which the result lists.


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("suite", SUITES)
@pytest.mark.parametrize("case", list(CASES))
def test_the_same_bad_input_has_the_same_outcome_in_every_suite(corpora, good_results, tmp_path, capsys, case,
                                                                suite):
    c = corpora[suite].moved(corpora[suite].pred.parent, tmp_path)
    shutil.copytree(corpora[suite].pred.parent, tmp_path, dirs_exist_ok=True, symlinks=True)
    make, outcome, named, says = CASES[case]
    archive = make(c)
    pred = archive if isinstance(archive, Path) else c.pred
    out = tmp_path / "results"
    shutil.copytree(good_results[suite], out)
    before = _snapshot(out)
    code, stdout, stderr = dyadbench(capsys, "score", pred, "--gt", c.gt, "--suite", suite, "--strict", "--out", out)
    assert code == STRICT_EXIT[outcome] or (outcome == "warning" and code == 1), stdout + stderr
    file = {"pred_file": c.pred_file, "gt_file": c.gt_file, "archive": f"{pred}[{c.stem}]"}.get(named)
    if outcome == "error":
        [line] = error_lines(stderr)
        assert line.startswith(f"error: {file}") and says in line
        assert _snapshot(out) == before  # nothing written over the previous good results
        return
    results = json.loads((out / "result.json").read_text())
    if outcome == "excluded":
        assert results["excluded"] == [{"clip": c.stem, "reason": results["excluded"][0]["reason"]}]
        assert says in results["excluded"][0]["reason"] and str(file) in results["excluded"][0]["reason"]
        assert "--strict" in stderr
    elif outcome == "missing":
        assert results["coverage"]["missing"] == [c.stem] and not results["excluded"]
    elif outcome == "extra":
        assert results["coverage"]["extra"] == ["zz_extra"] and results["coverage"]["missing"] == []
        assert any(says in note and "zz_extra" in note for note in results["notes"])
    else:
        warning = next(line for line in stderr.splitlines() if line.startswith("warning: "))
        assert warning.startswith(f"warning: {file}") and says in warning
        assert warning in results["notes"]
        assert code == 0 or results["excluded"] or results["coverage"]["missing"]


@pytest.mark.parametrize("suite", ["dualtalk", "gaze"])
@pytest.mark.parametrize("case", ["random bytes", "NaN in ground truth", "transposed ground truth"])
def test_score_gives_the_same_error_with_2_jobs_as_with_1(corpora, tmp_path, capsys, case, suite):
    c = corpora[suite].moved(corpora[suite].pred.parent, tmp_path)
    shutil.copytree(corpora[suite].pred.parent, tmp_path, dirs_exist_ok=True)
    CASES[case][0](c)
    lines = []
    for jobs in (1, 2):
        code, _, stderr = dyadbench(capsys, "score", c.pred, "--gt", c.gt, "--suite", suite, "--jobs", jobs)
        assert code == 2
        lines += error_lines(stderr)
    assert len(lines) == 2 and lines[0] == lines[1]


def test_eval_gives_the_same_error_with_2_jobs_as_with_1(tmp_path, capsys, monkeypatch):
    """A clip whose speech is corrupt is read in a worker with --jobs 2: the same one-line error."""
    monkeypatch.setenv("DYADBENCH_CACHE", str(tmp_path / "cache"))
    root = tmp_path / "data"
    assert dyadbench(capsys, "data", "synth", "--out", root, "--split", "test", "--clips", 3)[0] == 0
    bad = root / "test" / "synth_test_00002_speaker1.wav"  # read when the clip is streamed (motion is read earlier)
    bad.write_bytes(b"garbage, not a wav file")
    lines = []
    for jobs in (1, 2):
        out = tmp_path / f"run{jobs}"
        code, _, stderr = dyadbench(capsys, "eval", "--model", "zero", "--data", root, "--split", "test",
                                    "--jobs", jobs, "--out", out)
        assert code == 2 and not out.exists()
        lines += error_lines(stderr)
    assert lines == [f"error: {bad}: not a RIFF/WAVE file"] * 2


def _fails(item: int) -> int:
    if item == 3:
        raise InputError("clip 3", "cannot be read")
    return item * 10


def _init_fails(message: str) -> None:
    raise ConfigError(message)


class _Unpicklable(Exception):
    """An exception that cannot make the trip back: its constructor does not match its args (a pickled one
    cannot be rebuilt) and it holds a lock (cannot be pickled even where exception reducers are installed,
    as Dask's tblib does)."""

    def __init__(self, a, b):
        super().__init__(f"{a} and {b}")
        self.lock = threading.Lock()


def _raises_unpicklable(item: int) -> int:
    raise _Unpicklable(item, "b")


def test_worker_errors_reach_the_caller_unchanged():
    fork = get_context("fork")
    got = process_map(_fails, range(3), jobs=2, context=fork)
    assert list(got) == [0, 10, 20]
    with pytest.raises(InputError) as err:
        list(process_map(_fails, range(6), jobs=2, context=fork))
    assert str(err.value) == "clip 3: cannot be read" and err.value.source == "clip 3"
    # an initialiser's error does not break the pool: the first item raises it
    with pytest.raises(ConfigError, match="^no such model$"):
        list(process_map(_fails, range(4), jobs=2, context=fork, initializer=_init_fails,
                         initargs=("no such model",)))
    # an exception that cannot be sent back arrives as a RuntimeError naming it (not BrokenProcessPool)
    with pytest.raises(RuntimeError, match="^_Unpicklable in a worker process: 0 and b$"):
        list(process_map(_raises_unpicklable, range(2), jobs=2, context=fork))


@pytest.mark.parametrize("error", [InputError("a.npz[exp]", "bad"), InputError(None, "no items"),
                                   ConfigError("bad option"), OutputError("kept in /tmp/x")])
def test_errors_pickle_to_themselves(error):
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is type(error) and str(again) == str(error) and vars(again) == vars(error)
