"""``dyadbench train MODEL``: train a reference model. Sub-commands live beside each model."""

from __future__ import annotations

import click

from dyadbench.cli.lazy import lazy_group

TRAINERS: dict[str, tuple[str, str]] = {
    "timar": ("models.timar.cli:train_timar", "Faithful TIMAR (tiny/base/large)."),
    "timar-stream": ("models.timar.cli:train_timar_stream", "Streaming-native TIMAR variant."),
    "dualtalk": ("models.dualtalk.cli:train_dualtalk", "DualTalk, log-mel small variant."),
    "sfms-tokenizer": ("models.sfms.cli:train_tokenizer", "SFMS stage 1: sparse keyframe tokenizer."),
    "sfms": ("models.sfms.cli:train_predictor", "SFMS stage 2: listening-head predictor."),
    "stygazetalk-style": ("models.stygazetalk.cli:train_style_encoder",
                          "StyGazeTalk stage 1: contrastive style encoder."),
    "stygazetalk": ("models.stygazetalk.cli:train_generator", "StyGazeTalk stage 2: motion generator."),
}


@click.group(cls=lazy_group(TRAINERS, "Models"))
def train() -> None:
    """Train a reference model on a dataset (the embedded corpus by default).

    Single process by default; the same entry point runs data-parallel under torchrun, e.g.
    `torchrun --nproc_per_node 8 -m dyadbench train timar --config base`.
    """
