"""SFMS on REACT (the paper's Table II): R = 10 facial reactions per speaker sample, 25-d emotion features.

The REACT suite scores R = 10 listener reactions per speaker sample on REACT's 25-d emotion features
(15 action-unit occurrences, valence and arousal, 8 expression probabilities;
``shared/specs/metrics-react.md``). This module generates them with a trained SFMS and writes the
``predictions`` array (N, R, 750, 25) that ``dyadbench score --suite react`` reads::

    python -m models.sfms.react --data out/react-synth --split val --out out/react-preds/val/sfms.npz

Decisions where the paper is silent (numbered after the spec's, config D1..D33):

- **D19 (output space)**: the tokenizer and predictor model the 25-d emotion features themselves (the
  REACT adapter's motion, layout ``react25``): the checkpoint's output space *is* the metric space. The
  paper tokenises the 58-d FaceVerse coefficients and the spec's default decodes emotion with a separate
  head on the frozen tokenizer (predecessor practice); here there is no second model between the
  tokens and the scored features. Trained with ``--set dim=25`` (tokenizer) on the REACT layout.
- **D33 (speaker input, config field)**: ``speaker_audio = "none"``: the speaker is given by its 25-d
  emotion features (continuous, D13) over [t−40, t+8) (D14); the embedded corpus written in the REACT
  layout has no audio, and the paper's wav2vec2 features of the real wavs are not available offline.
- **D34 (valid ranges)**: each generated frame is mapped to REACT's ranges after denormalisation:
  action units clipped to [0, 1] (continuous occurrence scores, not binarised), valence and arousal to
  [−1, 1], expression probabilities clipped at 0 and renormalised to sum 1 (uniform 1/8 where all 8
  are ≤ 0). :func:`to_valid_range`.
- **D35 (reactions)**: the R reactions of a sample are R independent rollouts from a neutral past
  (spec §3.5 "REACT"), each sampled (D17: multinomial, temperature 1) from its own ``torch.Generator``
  seeded with ``derive_seed(seed, "sfms-react", speaker path, r)``: a reaction depends only on its
  (seed, sample, r), not on the batch it ran in or on the other samples.

Causality: the rolling loop (:func:`models.sfms.infer.roll`) generates frames [t, t+8) from speaker
frames [t−40, t+8) only, so speaker frames ≥ f never change output frames < 8·⌊f/8⌋ (a look-ahead of at
most 7 frames, 0.28 s, D14 "concurrent"). The REACT suite scores predictions on disk, not through the
streaming protocol, so the rollouts run offline with the whole speaker clip in memory.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import click
import numpy as np
import torch

from dyadbench import atomic
from dyadbench.cli.options import SEED
from dyadbench.datasets.react import EMOTION_DIM, REACT25, ReactSplit
from dyadbench.errors import InputError
from dyadbench.metrics.react import FRAMES, REACTIONS
from dyadbench.seeding import derive_seed
from dyadbench.training.checkpoint import file_digest
from models.sfms.bundle import SFMS, checkpoint_layout, load_sfms
from models.sfms.infer import Roller, roll

CHECKPOINT = Path(__file__).parent / "checkpoints" / "sfms-tiny-react.pt"
REPRODUCE = ("dyadbench data synth --layout react --split train --out out/react-synth && "
             "dyadbench train sfms-tokenizer --config tiny --dataset react --data out/react-synth --set dim=25 "
             "--export out/sfms-tok-react.pt && dyadbench train sfms --config tiny --dataset react --data "
             "out/react-synth --steps 8000 --set speaker_audio=none --set audio_bins=1 "
             "--tokenizer out/sfms-tok-react.pt --export models/sfms/checkpoints/sfms-tiny-react.pt")
AU, VA, EXPRESSION = REACT25.components["au"], REACT25.components["va"], REACT25.components["expression"]


def load_react_sfms(path: str | Path = CHECKPOINT) -> tuple[SFMS, dict]:
    """(model, meta) of an SFMS checkpoint trained on the REACT emotion features; any other checkpoint
    (another motion layout or dimension) is an InputError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, f"SFMS REACT checkpoint not found; train it with: {REPRODUCE}")
    model, meta = load_sfms(path)
    layout, dim = checkpoint_layout(meta), model.tokenizer.cfg.dim
    if layout != REACT25.name or dim != EMOTION_DIM:
        raise InputError(path, f"this SFMS checkpoint models {layout} motion ({dim} dims); REACT reactions need "
                               f"one trained on the {REACT25.name} emotion features ({EMOTION_DIM} dims), e.g. "
                               f"{CHECKPOINT.name}: {REPRODUCE}")
    return model, meta


def to_valid_range(frames: np.ndarray) -> np.ndarray:
    """D34: (..., 25) emotion frames mapped to REACT's ranges (AUs [0, 1], valence/arousal [−1, 1],
    expression probabilities ≥ 0 summing to 1; uniform where all are ≤ 0), float32."""
    out = np.array(frames, dtype=np.float32)
    if out.shape[-1] != EMOTION_DIM:
        raise InputError(None, f"emotion frames must have {EMOTION_DIM} features, got shape {out.shape}")
    out[..., AU] = np.clip(out[..., AU], 0.0, 1.0)
    out[..., VA] = np.clip(out[..., VA], -1.0, 1.0)
    probs = np.clip(out[..., EXPRESSION], 0.0, None)
    total = probs.sum(-1, keepdims=True)
    n = probs.shape[-1]
    out[..., EXPRESSION] = np.where(total > 0, probs / np.where(total > 0, total, 1.0), 1.0 / n)
    return out


def reaction_seed(seed: int, speaker: str, reaction: int) -> int:
    """D35: the seed of reaction ``reaction`` of the sample whose speaker path is ``speaker``."""
    return derive_seed(seed, "sfms-react", speaker, reaction)


@torch.no_grad()
def generate_reactions(model: SFMS, speaker: np.ndarray, names: list[str], *, reactions: int = REACTIONS,
                       seed: int = 0, batch: int = 200) -> np.ndarray:
    """(N, R, T, 25) float32 reactions to the speaker emotion clips ``speaker`` (N, T, 25), named by
    their speaker paths ``names`` (the per-reaction seeds, D35); ``batch`` rollouts run at once (the
    result does not depend on it)."""
    speaker = np.asarray(speaker, dtype=np.float32)
    if speaker.ndim != 3 or speaker.shape[-1] != model.tokenizer.cfg.dim:
        raise InputError(None, f"speaker features must be (N, T, {model.tokenizer.cfg.dim}), got {speaker.shape}")
    if len(names) != len(speaker):
        raise InputError(None, f"{len(names)} names for {len(speaker)} speaker clips")
    n, t, _ = speaker.shape
    cfg = model.predictor.cfg
    roller = Roller(model)
    jobs = [(k, r) for k in range(n) for r in range(reactions)]
    out = np.empty((n, reactions, t, EMOTION_DIM), dtype=np.float32)
    for lo in range(0, len(jobs), batch):
        part = jobs[lo: lo + batch]
        spk = model.tokenizer.normalise(torch.as_tensor(speaker[[k for k, _ in part]]))
        rows = torch.zeros(len(part), t * cfg.audio_rows_per_frame, cfg.audio_bins)  # D33: no audio branch
        generators = [torch.Generator().manual_seed(reaction_seed(seed, names[k], r)) for k, r in part]
        frames = model.tokenizer.denormalise(roll(roller, spk, rows, 0, t, generators)).numpy()
        for (k, r), f in zip(part, frames):
            out[k, r] = to_valid_range(f)
    return out


@click.command()
@click.option("--weights", type=click.Path(dir_okay=False, path_type=Path), default=CHECKPOINT, show_default=True,
              help="SFMS checkpoint trained on the REACT layout (25-d emotion features).")
@click.option("--data", type=click.Path(exists=True, file_okay=False, path_type=Path), required=True,
              help="REACT root (e.g. `dyadbench data synth --layout react --out DIR`).")
@click.option("--split", type=click.Choice(["val", "test"]), default="val", show_default=True)
@click.option("--reactions", type=click.IntRange(min=1), default=REACTIONS, show_default=True,
              help="Reactions per speaker sample (the REACT suite scores 10).")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of every reaction (D35).")
@click.option("--threads", type=click.IntRange(min=1), default=1, show_default=True, help="torch CPU threads.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The .npz to write: 'predictions' (N, R, 750, 25) in the split's mirrored sample order "
                   "(a JSON of the run beside it: <out>.json).")
def main(weights: Path, data: Path, split: str, reactions: int, seed: int, threads: int, out: Path) -> None:
    """Generate SFMS reactions for every sample of a REACT split, ready for `dyadbench score --suite react`."""
    torch.set_num_threads(threads)
    model, meta = load_react_sfms(weights)
    source = ReactSplit.open(data, split)
    _, speaker = source.ground_truth(FRAMES)
    names = [s for s, _ in source.samples]
    predictions = generate_reactions(model, speaker, names, reactions=reactions, seed=seed)
    atomic.save_npz(out, predictions=predictions)
    command = "python -m models.sfms.react " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    atomic.write_json(out.with_name(out.name + ".json"), {
        "command": command, "weights": str(weights), "weights_sha256": file_digest(weights), "data": str(data),
        "split": split, "samples": len(names), "reactions": reactions, "frames": FRAMES, "seed": seed,
        "seeds": "derive_seed(seed, 'sfms-react', speaker path, r) per reaction (D35)",
        "train_meta": {k: meta.get(k) for k in ("preset", "seed", "best_val_ce", "best_step", "train_seconds")}})
    click.echo(f"wrote {out}: predictions {predictions.shape}")


if __name__ == "__main__":
    main()
