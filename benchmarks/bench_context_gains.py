"""Models' own context gains next to the model-free context headroom, per embedded corpus.

For every model with committed result files at n = 0, 3 and 7 (default protocol settings: no guidance, causal
speech normalisation, default tail and history policy, no perturbation), the change of MSE exp, P-FD exp and
FD exp from n = 0 to n = 3 and n = 7, next to the same change of the ridge headroom estimator
(``benchmarks/results/context_headroom.json``, :mod:`dyadbench.headroom`). Values are the leaderboards'
publication-scaled means. The estimator is scored on the first 200 dialogues of each split; the models on the
clips their result files name (whole splits, SFMS its first 20 dialogues), so compare changes, not levels.

    python benchmarks/bench_context_gains.py [--results results/] [--datasets synthetic,synthetic-v2]
        # writes benchmarks/results/context_gains.{json,md}
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dyadbench.protocol.config import DEFAULT_CFG_SCALE, ProtocolConfig  # noqa: E402
from dyadbench.results import results_frame  # noqa: E402
from output import RESULTS, ROOT, write_result  # noqa: E402  (benchmarks/output.py)

CONTEXTS = (0, 3, 7)
METRICS = ("mse_exp", "pfd_exp", "fd_exp")
HEADER = {"mse_exp": "MSE exp", "pfd_exp": "P-FD exp", "fd_exp": "FD exp"}
SPLITS = ("test", "ood")
ESTIMATOR = "headroom estimator (ridge)"


def default_runs(frame):
    """Rows of runs made with the protocol's default settings (the leaderboards' unlabelled rows)."""
    default = ProtocolConfig()
    keep = ((frame["cfg_scale"] == DEFAULT_CFG_SCALE) & (frame["speech_norm"] == default.speech_norm)
            & (frame["tail"] == default.tail) & (frame["history_agent"] == default.history_agent)
            & (frame["turn_seconds"] == default.turn_seconds) & (frame["seed"] == default.seed))
    return frame[keep & (frame["protocol"] == "streaming") & ~frame["oracle"].astype(bool)]


def model_values(frame, dataset: str, split: str) -> dict[str, dict]:
    """model -> {"clips": clips at n = 7, "values": {metric: {n: scaled mean}}}, models with every n only."""
    part = frame[(frame["dataset"] == dataset) & (frame["split"] == split) & frame["metric"].isin(METRICS)]
    out = {}
    for model, rows in part.groupby("model", sort=True):
        values = {m: {int(n): float(v) for n, v in zip(r["context"], r["scaled"])}
                  for m, r in rows.groupby("metric")}
        if all(set(CONTEXTS) <= set(values.get(m, {})) for m in METRICS):
            out[model] = {"clips": int(rows.loc[rows["context"] == CONTEXTS[-1], "clips"].iloc[0]),
                          "values": {m: {n: values[m][n] for n in CONTEXTS} for m in METRICS}}
    return out


def estimator_values(headroom: dict, dataset: str, split: str) -> dict | None:
    """The headroom estimator's row in the same shape, or None when the headroom file lacks that corpus."""
    corpus = headroom["data"]["corpora"].get(dataset)
    if corpus is None or split not in corpus["splits"]:
        return None
    means = corpus["splits"][split]["means"]
    return {"clips": int(corpus["splits"][split]["dialogues"]),
            "values": {m: {n: float(means[str(n)][m]) for n in CONTEXTS} for m in METRICS}}


def change(value: float, base: float) -> str:
    return "—" if base == 0 or not math.isfinite(base) else f"{100 * (value / base - 1):+.1f} %"


def table(rows: dict[str, dict]) -> list[str]:
    head = ["model", "dialogues"] + [f"{HEADER[m]} n = 0" for m in METRICS] + \
        [f"{HEADER[m]} Δ n = {n}" for m in METRICS for n in CONTEXTS[1:]]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for model, row in rows.items():
        v = row["values"]
        cells = [model, str(row["clips"])] + [f"{v[m][0]:.4g}" for m in METRICS] + \
            [change(v[m][n], v[m][0]) for m in METRICS for n in CONTEXTS[1:]]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", default=str(ROOT / "results"), help="folder of result files")
    parser.add_argument("--headroom", default=str(RESULTS / "context_headroom.json"))
    parser.add_argument("--datasets", default="synthetic,synthetic-v2")
    parser.add_argument("--out", default="context_gains")
    args = parser.parse_args(argv)
    frame = default_runs(results_frame([args.results]))
    headroom = json.loads(Path(args.headroom).read_text())
    lines = ["# Context gains of the models next to the context headroom", "",
             "Change of each model's publication-scaled mean from n = 0 to n = 3 and n = 7 history turns "
             "(default protocol settings), and the same change for the model-free headroom estimator "
             "(`benchmarks/results/context_headroom.md`). Negative is better (all three are errors). "
             "The estimator is scored on the first 200 dialogues of the split, each model on the dialogues "
             "its result files name: compare the changes, not the levels.", ""]
    data = {}
    for dataset in args.datasets.split(","):
        for split in SPLITS:
            rows = model_values(frame, dataset, split)
            estimator = estimator_values(headroom, dataset, split)
            if estimator is not None:
                rows[ESTIMATOR] = estimator
            if not rows:
                continue
            data[f"{dataset}/{split}"] = rows
            lines += [f"## {dataset} {split}", "", *table(rows), ""]
    if not data:
        raise SystemExit(f"no result files with n = {', '.join(map(str, CONTEXTS))} under {args.results}")
    print("\n".join(lines))
    write_result(RESULTS / args.out, "\n".join(lines), seed=None, data=data)


if __name__ == "__main__":
    main()
