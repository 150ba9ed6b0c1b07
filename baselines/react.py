"""REACT's official trivial baselines (``shared/specs/metrics-react.md``), R = 10 reactions per sample.

- **GT**: the sample's real listener reaction, repeated R times (copies the ground truth: an oracle);
- **Random**: every value uniform in [0, 1), seeded;
- **Mime**: the speaker's own features, repeated R times;
- **MeanSeq**: the per-frame mean over every person of the train split (T, 25), repeated;
- **MeanFr**: that mean also averaged over time: one constant 25-d vector.

Each is a pure function of the split's arrays returning (N, R, T, 25) float32 in the split's mirrored
sample order; ``python -m baselines.react NAME --data ROOT --split val --out X.npz`` writes the
``predictions`` array that ``dyadbench score --suite react`` reads. Checks that follow from the
definitions (tested): MeanFr gives FRCorr = 0, FRDiv = FRVar = FRDvs = 0, FRSyn = 49; Random gives
FRDiv ≈ 1/6, FRVar ≈ 1/12, FRDvs ≈ 1/6; GT and Mime have FRDiv = 0.
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from dyadbench import atomic
from dyadbench.cli.options import SEED
from dyadbench.datasets.react import ReactSplit
from dyadbench.errors import InputError
from dyadbench.metrics.react import FRAMES, REACTIONS
from dyadbench.seeding import derive_seed

NAMES = ("gt", "random", "mime", "mean-seq", "mean-fr")
ORACLES = ("gt",)


def _repeat(clips: np.ndarray, reactions: int) -> np.ndarray:
    """(N, T, 25) -> (N, R, T, 25) float32, every reaction the same clip."""
    clips = np.asarray(clips, dtype=np.float32)
    return np.repeat(clips[:, None], reactions, axis=1)


def gt(listener: np.ndarray, reactions: int = REACTIONS) -> np.ndarray:
    """The real listener reactions (N, T, 25), each repeated R times."""
    return _repeat(listener, reactions)


def mime(speaker: np.ndarray, reactions: int = REACTIONS) -> np.ndarray:
    """The speaker's features (N, T, 25), each repeated R times."""
    return _repeat(speaker, reactions)


def random(samples: int, frames: int, seed: int, reactions: int = REACTIONS, dim: int = 25) -> np.ndarray:
    """Uniform [0, 1) values (N, R, T, dim) float32 from ``numpy`` seeded with ``derive_seed(seed, "react-random")``."""
    rng = np.random.default_rng(derive_seed(seed, "react-random"))
    return rng.random((samples, reactions, frames, dim), dtype=np.float32)


def mean_sequence(train: list[np.ndarray], frames: int) -> np.ndarray:
    """(T, 25) float64: the per-frame mean over the train people's clips (each cut to ``frames``)."""
    short = [i for i, a in enumerate(train) if len(a) < frames]
    if not train or short:
        raise InputError("train split", f"MeanSeq needs train clips of ≥ {frames} frames "
                                        f"({'none given' if not train else f'{len(short)} are shorter'})")
    return np.mean(np.stack([np.asarray(a[:frames], np.float64) for a in train]), axis=0)


def mean_seq(train_mean: np.ndarray, samples: int, reactions: int = REACTIONS) -> np.ndarray:
    """MeanSeq: the train per-frame mean (T, 25) for every sample and reaction."""
    return np.broadcast_to(np.asarray(train_mean, np.float32), (samples, reactions, *np.shape(train_mean))).copy()


def mean_fr(train_mean: np.ndarray, samples: int, reactions: int = REACTIONS) -> np.ndarray:
    """MeanFr: the train mean (T, 25) averaged over time, a constant frame, for every sample and reaction."""
    train_mean = np.asarray(train_mean, np.float64)
    frame = np.broadcast_to(train_mean.mean(axis=0), train_mean.shape)
    return mean_seq(frame, samples, reactions)


def predictions(name: str, root: str | Path, split: str, *, seed: int = 0, reactions: int = REACTIONS,
                frames: int = FRAMES) -> np.ndarray:
    """Baseline ``name`` (:data:`NAMES`) for every sample of ``root``'s ``split`` (mirrored order);
    MeanSeq and MeanFr read ``root``'s train split."""
    if name not in NAMES:
        raise InputError(None, f"unknown REACT baseline {name!r} (known: {', '.join(NAMES)})")
    data = ReactSplit.open(root, split)
    listener, speaker = data.ground_truth(frames)
    if name == "gt":
        return gt(listener, reactions)
    if name == "mime":
        return mime(speaker, reactions)
    if name == "random":
        return random(len(listener), frames, seed, reactions)
    train = ReactSplit.open(root, "train")
    mean = mean_sequence(list(train.emotions(frames).values()), frames)
    return (mean_seq if name == "mean-seq" else mean_fr)(mean, len(listener), reactions)


@click.command()
@click.argument("name", type=click.Choice(NAMES))
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), required=True,
              help="REACT root (MeanSeq/MeanFr also read its train split).")
@click.option("--split", type=click.Choice(["val", "test"]), default="val", show_default=True)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of Random.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The .npz to write ('predictions' (N, 10, 750, 25), mirrored sample order).")
def main(name: str, data: Path, split: str, seed: int, out: Path) -> None:
    """Write REACT trivial-baseline predictions NAME for a split."""
    array = predictions(name, data, split, seed=seed)
    atomic.save_npz(out, predictions=array)
    click.echo(f"wrote {out}: {name} predictions {array.shape}")


if __name__ == "__main__":
    main()
