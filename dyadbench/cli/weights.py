"""``dyadbench weights``: convert released checkpoints into native dyadbench checkpoints once."""

from __future__ import annotations

from pathlib import Path

import click

from dyadbench.cli.options import COUNT


@click.group("weights")
def weights() -> None:
    """Convert released model checkpoints into dyadbench checkpoints."""


@weights.command("convert")
@click.argument("source", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Native dyadbench checkpoint to write (atomically), e.g. timar-native.pt.")
@click.option("--heads", type=COUNT, default=None,
              help="Attention heads, which the released file does not store [default: from its model factory: "
                   "timar_base 12, timar_large 16, timar_huge 16; needed for any other factory].")
@click.option("--wav2vec", "wav2vec", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              help="Local wav2vec 2.0 folder the model will run with: checked to give the feature width the "
                   "checkpoint expects (speech_snippet_embed_dim).")
def convert(source: Path, out: Path, heads: int | None, wav2vec: Path | None) -> None:
    """Convert the released TIMAR checkpoint SOURCE (main.py's save_model format) into a native file.

    \b
    The file is read with torch.load(weights_only=True), allowing only argparse.Namespace and numpy's
    array globals; its model_ema weights (what the release evaluates with) are mapped onto dyadbench's
    `timar` model, every tensor accounted for. Later runs load OUT without converting and give the same
    predictions as the released file converted in memory:
      dyadbench weights convert TIMAR.pth --wav2vec wav2vec2-large-960h-lv60-self/ --out timar-native.pt
      dyadbench eval --model timar --weights timar-native.pt --wav2vec wav2vec2-large-960h-lv60-self/ \\
          --speech-norm clip --data DualTalk/ --split test --context 7
    The result records the native file's digest and the released file it came from.
    """
    from dyadbench.errors import ConfigError  # noqa: PLC0415  (keeps --help fast)
    from dyadbench.outputs import check_file  # noqa: PLC0415
    from dyadbench.training.checkpoint import save_checkpoint  # noqa: PLC0415
    from models.timar.official import load_official  # noqa: PLC0415

    check_file(out, f"--out {out}")
    model, meta = load_official(source, heads=heads)
    if wav2vec is not None:
        from dyadbench.features.wav2vec import load_wav2vec  # noqa: PLC0415

        width = int(load_wav2vec(wav2vec).config.hidden_size)
        if width != model.cfg.speech_dim:
            raise ConfigError(f"the wav2vec 2.0 model at {wav2vec} gives {width}-d features; {source} expects "
                              f"{model.cfg.speech_dim}-d (speech_snippet_embed_dim)")
    meta = {**meta, "format": "native"}
    meta.pop("dyadbench_version")  # save_checkpoint records the version that writes the file
    path = save_checkpoint(out, model_state=model.state_dict(), config=model.cfg.to_dict(), meta=meta)
    click.echo(f"wrote {path} (timar, {model.cfg.name}: D={model.cfg.dim}, {model.cfg.depth} blocks, "
               f"{model.cfg.heads} heads; model_ema weights of {source})")
