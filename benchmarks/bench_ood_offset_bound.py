"""How much of FD on the ood split is the unseen people's own mean pose, and what it costs any model.

FD per clip is ‖μ_p − μ_g‖² (the mean term) plus a covariance term (`frechet_terms`). Under the
protocol the agent's own motion is never an input (history agent motion is masked), and in the embedded
corpus every person's constants (jaw rest opening, expression offset, head mean) are drawn
independently of everything else, so a model trained on the train split can only place a clip's mean
where the training population (or the inputs) suggests. The ood people come from another style pool
(`dyadbench.synth.styles`: e.g. jaw rest U(0.02, 0.07) rad against U(0, 0.05) in training). Rows, per
split and component, averaged over every agent of the split:

- `GT at the train mean`: the ground truth itself, moved so that its clip mean is the training split's
  mean frame (perfect dynamics, identity-blind offset). Its covariance term is 0, so its FD is exactly
  the squared distance of each person's mean from the training population's mean.
- `GT, only its jaw rest at the train people's mean`: the ground truth with just the jaw-opening rest
  constant of its person (a style parameter, recorded by the generator) replaced by the training
  people's mean rest: the part of the mean no input reveals, alone.
- `GT at the partner's mean`: the ground truth moved to the partner's clip mean (the offset mime uses).
- `mime`: the partner's ground truth (the baseline), split into its two terms.
- with `--pred NAME=DIR` (a `dyadbench eval` predictions folder, repeatable): that model's two terms,
  all rows then restricted to the agents the folders predict.

    python benchmarks/bench_ood_offset_bound.py     # writes benchmarks/results/ood_offset_bound.md
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from output import write_result  # noqa: E402  (benchmarks/output.py)
from dyadbench.datasets.dualtalk_files import load_prediction  # noqa: E402
from dyadbench.metrics.dualtalk import SCALE, truncate_to_shortest  # noqa: E402
from dyadbench.metrics.frechet import frechet_terms  # noqa: E402
from dyadbench.motion import FLAME56, FLAME_COMPONENTS  # noqa: E402
from dyadbench.registry import DATASETS  # noqa: E402
from dyadbench.datasets.synthetic import DEFAULT_SEED  # noqa: E402
from dyadbench.synth.styles import STYLE_RANGES, style_pool  # noqa: E402

JAW_REST = {s.identity: s.jaw_rest for pool in STYLE_RANGES for s in style_pool(pool, DEFAULT_SEED)}
JAW_OPENING = FLAME56.components["jaw"].start  # jaw 0 = opening (dyadbench.synth.corpus)
OUT = Path(__file__).resolve().parent / "results" / "ood_offset_bound.md"


def load_split(split: str) -> dict[str, tuple[np.ndarray, np.ndarray, float]]:
    """{'<clip>_speakerK': (agent motion, partner motion, agent's jaw rest)} of every agent of a split."""
    agents = {}
    for clip in DATASETS.load("synthetic")(None, split):
        for me in clip.participants:
            partner = clip.partner_of(me.name)
            agents[f"{clip.clip_id}_{me.name}"] = (me.motion.astype(np.float64), partner.motion.astype(np.float64),
                                                   JAW_REST[me.identity])
    return agents


def train_means() -> tuple[np.ndarray, float]:
    """The training split's mean frame (every frame of every person) and mean jaw rest (every agent)."""
    total, frames, rests = np.zeros(FLAME56.dim), 0, []
    for clip in DATASETS.load("synthetic")(None, "train"):
        for person in clip.participants:
            total += person.motion.sum(axis=0)
            frames += len(person.motion)
            rests.append(JAW_REST[person.identity])
    return total / frames, float(np.mean(rests))


def terms(rows: dict[str, list[tuple[float, float]]], name: str, pred: np.ndarray, gt: np.ndarray) -> None:
    for c in FLAME_COMPONENTS:
        s = FLAME56.components[c]
        rows.setdefault(f"{name}|{c}", []).append(frechet_terms(*truncate_to_shortest(pred[:, s], gt[:, s])))


def table(agents: dict[str, tuple[np.ndarray, np.ndarray, float]], mean: np.ndarray, rest: float,
          preds: dict[str, Path]) -> tuple[list[str], dict[str, np.ndarray]]:
    rows: dict[str, list[tuple[float, float]]] = {}
    names = ["GT at the train mean", "GT, only its jaw rest at the train people's mean", "GT at the partner's mean",
             "mime"] + list(preds)
    for agent, (g, a, own_rest) in agents.items():
        g, a = truncate_to_shortest(g, a)
        terms(rows, names[0], g - g.mean(axis=0) + mean, g)
        moved = g.copy()
        moved[:, JAW_OPENING] += rest - own_rest
        terms(rows, names[1], moved, g)
        terms(rows, names[2], g - g.mean(axis=0) + a.mean(axis=0), g)
        terms(rows, names[3], a, g)
        for name, folder in preds.items():
            terms(rows, name, load_prediction(folder / f"{agent}.npy"), g)
    return names, {k: np.mean(v, axis=0) for k, v in rows.items()}


def render(split: str, n_agents: int, names: list[str], means: dict[str, np.ndarray]) -> list[str]:
    lines = [f"### {split} ({n_agents} agents)", "",
             "| row | " + " | ".join(f"FD {c} (mean + cov)" for c in FLAME_COMPONENTS) + " |",
             "|---|" + "---|" * len(FLAME_COMPONENTS)]
    for name in names:
        cells = []
        for c in FLAME_COMPONENTS:
            mean_term, cov_term = (round(v, 3) + 0.0 for v in means[f"{name}|{c}"] * SCALE[f"fd_{c}"])  # no "-0.000"
            cells.append(f"{mean_term + cov_term:.3f} ({mean_term:.3f} + {cov_term:.3f})")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines + [""]


def _pred_option(values: tuple[str, ...]) -> dict[str, Path]:
    preds = {}
    for value in values:
        name, sep, folder = value.partition("=")
        if not sep or not Path(folder).is_dir():
            raise click.BadParameter(f"expected NAME=DIR with an existing predictions folder, got {value!r}")
        preds[name] = Path(folder)
    return preds


@click.command(help=__doc__)
@click.option("--splits", default="test,ood", show_default=True)
@click.option("--pred", "pred", multiple=True, help="NAME=DIR: a predictions folder of `dyadbench eval` "
              "(give its split with --splits); rows are then restricted to the agents it predicts.")
@click.option("--out", default=OUT, show_default=True, type=click.Path(dir_okay=False, path_type=Path))
def main(splits: str, pred: tuple[str, ...], out: Path) -> None:
    preds = _pred_option(pred)
    mean, rest = train_means()
    lines = ["# FD on unseen people: the mean term", "",
             "Produced by `python benchmarks/bench_ood_offset_bound.py" + "".join(f" --pred {shlex.quote(p)}" for p in pred)
             + f" --splits {splits}` (embedded corpus; FD in publication scaling: jaw ×10³, pose ×10²; "
             "each cell is the mean over agents of FD = mean term + covariance term).", ""]
    for split in splits.split(","):
        agents = load_split(split)
        if preds:
            agents = {k: v for k, v in agents.items() if all((f / f"{k}.npy").exists() for f in preds.values())}
            if not agents:
                raise click.UsageError(f"no agent of the {split} split is predicted by every --pred folder")
        names, means = table(agents, mean, rest, preds)
        lines += render(split, len(agents), names, means)
        click.echo(f"{split}: {len(agents)} agents", err=True)
    text = "\n".join(lines)
    write_result(out, text, seed=DEFAULT_SEED)
    click.echo(text)


if __name__ == "__main__":
    main()
