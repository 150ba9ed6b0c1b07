"""``dyadbench weights``: convert released checkpoints into native dyadbench checkpoints once.

Converters live beside their models and are imported only when invoked (the core never imports a model).
"""

from __future__ import annotations

import click

from dyadbench.cli.lazy import lazy_group

CONVERTERS: dict[str, tuple[str, str]] = {
    "convert": ("models.timar.cli:convert_official",
                "Released TIMAR checkpoint (main.py's save_model format) -> native timar checkpoint."),
}


@click.group("weights", cls=lazy_group(CONVERTERS, "Converters"))
def weights() -> None:
    """Convert released model checkpoints into dyadbench checkpoints.

    The released DualTalk checkpoint (a bare state dict) needs no conversion: pass it to
    `dyadbench eval --model dualtalk|dualtalk-offline --weights DualTalk.pth --wav2vec PATH`.
    """
