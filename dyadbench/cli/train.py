"""``dyadbench train MODEL``: train a reference model. Sub-commands live beside each model."""

from __future__ import annotations

import importlib

import click

TRAINERS: dict[str, tuple[str, str]] = {
    "timar": ("models.timar.cli:train_timar", "Faithful TIMAR (tiny/base/large)."),
    "timar-stream": ("models.timar.cli:train_timar_stream", "Streaming-native TIMAR variant."),
    "sfms-tokenizer": ("models.sfms.cli:train_tokenizer", "SFMS stage 1: sparse keyframe tokenizer."),
    "sfms": ("models.sfms.cli:train_predictor", "SFMS stage 2: listening-head predictor."),
    "stygazetalk-style": ("models.stygazetalk.cli:train_style_encoder",
                          "StyGazeTalk stage 1: contrastive style encoder."),
    "stygazetalk": ("models.stygazetalk.cli:train_generator", "StyGazeTalk stage 2: motion generator."),
}


class _LazyTrainers(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(TRAINERS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in TRAINERS:
            return None
        module_name, _, attr = TRAINERS[cmd_name][0].partition(":")
        return getattr(importlib.import_module(module_name), attr)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Models"):
            formatter.write_dl([(n, h) for n, (_, h) in TRAINERS.items()])


@click.group(cls=_LazyTrainers)
def train() -> None:
    """Train a reference model on a dataset (the embedded corpus by default).

    Single process by default; the same entry point runs data-parallel under torchrun, e.g.
    `torchrun --nproc_per_node 8 -m dyadbench train timar --config base`.
    """
