"""``dyadbench models`` and ``dyadbench datasets``: list the registries without importing any entry."""

from __future__ import annotations

import click

from dyadbench.registry import DATASETS, MODELS, SUITES, Registry


def _table(registry: Registry, with_tags: bool) -> str:
    entries = [registry.get(n) for n in registry.names()]
    width = max(len(e.name) for e in entries)
    lines = []
    for e in entries:
        tags = f"[{', '.join(e.tags)}] " if with_tags and e.tags else ""
        lines.append(f"  {e.name.ljust(width)}  {tags}{e.summary}")
    return "\n".join(lines)


@click.command()
@click.option("--targets", is_flag=True, help="Also show the module:attribute each name is loaded from.")
def models(targets: bool) -> None:
    """List registered models and baselines (tags: baseline, reference, oracle, gaze, guidance).

    Models tagged 'guidance' have classifier-free guidance: only they take eval/sweep --cfg-scale.

    Models tagged 'oracle' read the agent's ground truth: they check the pipeline and are never ranked.
    """
    click.echo("models:")
    click.echo(_table(MODELS, with_tags=True))
    if targets:
        click.echo("\n".join(f"  {n}: {MODELS.get(n).target}" for n in MODELS.names()))


@click.command()
@click.option("--targets", is_flag=True, help="Also show the module:attribute each name is loaded from.")
def datasets(targets: bool) -> None:
    """List registered datasets (for --dataset) and metric suites (for --suite)."""
    for title, registry in (("datasets", DATASETS), ("metric suites", SUITES)):
        click.echo(f"{title}:")
        click.echo(_table(registry, with_tags=False))
        if targets:
            click.echo("\n".join(f"  {n}: {registry.get(n).target}" for n in registry.names()))
