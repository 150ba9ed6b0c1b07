"""Helpers of the hostile-input tests: the real command line in-process, small corpora."""

from __future__ import annotations

from pathlib import Path

from dyadbench.cli import main
from dyadbench.synth.corpus import make_clip
from dyadbench.synth.writers import write_clip

SECONDS = 4.0  # short dialogues: four 1-s turns each, so every run streams in well under a second


def run_cli(capsys, *args) -> tuple[int, str, str]:
    """Run ``dyadbench ARGS`` through its entry point: (exit status, stdout, stderr)."""
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def dyadbench(capsys, *args) -> tuple[int, str]:
    """Run ``dyadbench ARGS`` through its entry point: (exit status, stdout + stderr)."""
    code, out, err = run_cli(capsys, *args)
    return code, out + err


def write_dialogues(folder: Path, split: str, n: int, seed: int = 0) -> Path:
    """``n`` synthetic dialogues of ``split`` (ids ``synth_<split>_0000i``) as DualTalk files in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        write_clip(folder, make_clip(split, i, seed=seed, duration_s=SECONDS), seed=seed)
    return folder


def write_root(root: Path, train: int, test: int) -> Path:
    """A DualTalk root holding ``train/`` and ``test/`` with that many short dialogues each."""
    write_dialogues(root / "train", "train", train)
    write_dialogues(root / "test", "test", test)
    return root


def error_line(output: str) -> str:
    """The one ``error: ...`` line of a refused command (and no traceback)."""
    assert "Traceback" not in output, output
    lines = [line for line in output.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, output
    return lines[0]
