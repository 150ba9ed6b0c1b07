"""Context headroom of the embedded corpora: how much n = 0 … 7 visible history turns can lower the error.

A model-free estimator (:mod:`dyadbench.headroom`: ridge regression from features of exactly what the
streaming protocol hands a model — the partner's motion and speech and the agent's own speech of the
current turn and of n history turns, never the agent's own motion) is fitted on each corpus's train split
for every n, its penalty chosen on val, and scored on test and ood with the benchmark's FD, P-FD and MSE per
component, scaled as the leaderboards print them. The estimator's design was fixed on v1 train/val.

    python benchmarks/bench_context_headroom.py [--datasets synthetic,synthetic-v2] [--train-clips 400]
        [--val-clips 100] [--test-clips 200] [--ood-clips 200]
        # writes benchmarks/results/context_headroom.{json,md,png}
    python benchmarks/bench_context_headroom.py --render
        # re-renders context_headroom.md (and the markdown kept in the .json) and the .png from the .json's data
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench import strict_json  # noqa: E402
from dyadbench.errors import ConfigError, DyadbenchError  # noqa: E402
from dyadbench.headroom import features  # noqa: E402
from dyadbench.headroom.estimate import measure  # noqa: E402
from dyadbench.headroom.report import plot, render, save_texts  # noqa: E402
from dyadbench.headroom.ridge import HISTORY_RATIOS, LAMBDAS  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from output import RESULTS, render_markdown, result_paths, write_result  # noqa: E402  (benchmarks/output.py)

SEED = 0
EVAL_SPLITS = ("test", "ood")


def design(clips: dict[str, int], plot_path: Path) -> dict:
    """What the estimator is, in numbers and one paragraph (recorded with the result)."""
    lags = ", ".join(str(x) for x in features.SPEECH_LAGS)
    summary = (
        "Estimator (`dyadbench/headroom/`): ridge regression, closed form, from the inputs the streaming protocol "
        "gives a model to the agent's motion of the current turn, frame by frame. Every n uses the same "
        f"current-turn block ({features.CURRENT_DIM} columns: both people's log-mel in {features.MEL_GROUPS} band "
        f"groups at causal lags {lags} frames, the partner's motion at lags "
        f"{', '.join(str(x) for x in features.MOTION_LAGS)} frames, and their turn means) plus, per history "
        f"turn d = 1 … n, its own weights on that turn's summary ({features.SUMMARY_DIM} columns: partner motion "
        "means and log spreads per component, both people's band means and speaking fractions, turn present). "
        f"Penalty λ per component from {len(LAMBDAS)} values in [{LAMBDAS[0]:g}, {LAMBDAS[-1]:g}], the history "
        f"turns' penalty r·λ with r in {{{', '.join(f'{r:g}' for r in HISTORY_RATIOS)}}}, chosen on val. "
        "Scores: the suite's MSE, P-FD and FD per component on each direction's whole turns concatenated, mean "
        "over directions, publication scale. The design was chosen on v1 train/val before any v2 test number "
        "was seen. Deterministic; the change intervals resample dialogues (seed "
        f"{SEED}). Clips per split: the first N sorted ids ({', '.join(f'{s} {c}' for s, c in clips.items())}).")
    return {"summary": summary, "plot": str(plot_path.relative_to(RESULTS.parents[1])
                                             if plot_path.is_relative_to(RESULTS.parents[1]) else plot_path),
            "max_context": features.MAX_CONTEXT, "current_dim": features.CURRENT_DIM,
            "summary_dim": features.SUMMARY_DIM, "speech_lags": list(features.SPEECH_LAGS),
            "motion_lags": list(features.MOTION_LAGS), "mel_groups": features.MEL_GROUPS,
            "speaking_db": features.SPEAKING_DB, "lambdas": list(LAMBDAS), "history_ratios": list(HISTORY_RATIOS),
            "eval_splits": list(EVAL_SPLITS)}


def run(datasets: list[str], clips: dict[str, int], root: Path | None, plot_path: Path, progress: bool) -> dict:
    """``{"design": ..., "corpora": {dataset: measure(...)}}`` for each dataset name."""
    corpora = {}
    for name in datasets:
        opener = DATASETS.load(name)
        corpora[name] = measure(lambda split: opener(root, split), clips, eval_splits=EVAL_SPLITS, seed=SEED,
                                progress=progress)
    return {"design": design(clips, plot_path), "corpora": corpora}


def rerender(out: Path) -> tuple[Path, Path]:
    """Re-render the .md (and the .json's markdown) and the .png of ``out`` from the .json's data alone."""
    json_path, md_path = result_paths(out)
    try:
        record = strict_json.loads(json_path.read_text(encoding="utf-8"))
        data = record["data"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"{json_path}: not a context-headroom result file ({exc})") from None
    record["markdown"] = render(data)
    plot(data, json_path.with_suffix(".png"))
    save_texts({json_path: strict_json.dumps(record), md_path: render_markdown(record)})
    return json_path, md_path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default="synthetic", help="Comma-separated dataset names (registry).")
    parser.add_argument("--root", type=Path, default=None, help="Dataset root (default: the embedded corpus).")
    for split, default in (("train", 400), ("val", 100), ("test", 200), ("ood", 200)):
        parser.add_argument(f"--{split}-clips", type=int, default=default)
    parser.add_argument("--out", type=Path, default=RESULTS / "context_headroom",
                        help="Result to write (.json, .md, .png) [default: benchmarks/results/context_headroom].")
    parser.add_argument("--render", action="store_true", help="Only re-render .md and .png from the .json.")
    parser.add_argument("--quiet", action="store_true", help="No progress bars.")
    args = parser.parse_args(argv)
    try:
        if args.render:
            for path in rerender(args.out):
                print(f"wrote {path}")
            return
        clips = {"train": args.train_clips, "val": args.val_clips, "test": args.test_clips, "ood": args.ood_clips}
        if min(clips.values()) < 1:
            raise ConfigError(f"every split needs at least one clip, got {clips}")
        plot_path = result_paths(args.out)[0].with_suffix(".png")
        data = run(args.datasets.split(","), clips, args.root, plot_path, progress=not args.quiet)
        text = render(data)
        print(text)
        plot(data, plot_path)
        write_result(args.out, text, seed=SEED, data=data,
                     argv=None if argv is None else [sys.argv[0], *argv])
    except DyadbenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
