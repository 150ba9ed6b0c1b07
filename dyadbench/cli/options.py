"""Click parameter types with the domain of every numeric option, so a bad value is a usage error (exit 2).

Every numeric option of every command uses one of these (or ``click.IntRange``) instead of a bare
``int``/``float``: counts are positive, seeds are non-negative, real values are finite and within their
range. ``click.FloatRange`` alone lets ``nan`` (and ``inf`` when unbounded) through; :func:`real` does not.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Iterable

import click

#: A seed: any non-negative integer (recorded in results and checkpoints).
SEED = click.IntRange(min=0)
#: A count of things (steps, clips, threads, windows ...).
COUNT = click.IntRange(min=1)


class FiniteFloatRange(click.FloatRange):
    """``click.FloatRange`` that also refuses ``nan`` and ``±inf``."""

    name = "finite float range"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{rv} is not a finite number.", param, ctx)
        return rv


def real(min: float | None = None, max: float | None = None, *, min_open: bool = False,
         max_open: bool = False) -> FiniteFloatRange:
    """A finite float in the given range, e.g. ``real(0, min_open=True)`` for a positive number."""
    return FiniteFloatRange(min=min, max=max, min_open=min_open, max_open=max_open)


#: A positive finite number (seconds, learning rates ...).
POSITIVE = real(0, min_open=True)
#: A non-negative finite number.
NON_NEGATIVE = real(0)


class IntList(click.ParamType):
    """Comma-separated integers, each at least ``min``, e.g. ``--contexts 0,3,7``."""

    name = "integers"

    def __init__(self, min: int = 0) -> None:
        self.min = min

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, list):
            return value
        items = [v.strip() for v in str(value).split(",") if v.strip()]
        if not items:
            self.fail("needs at least one value.", param, ctx)
        try:
            numbers = [int(v) for v in items]
        except ValueError:
            self.fail(f"expected comma-separated integers, got {value!r}.", param, ctx)
        low = [n for n in numbers if n < self.min]
        if low:
            self.fail(f"{', '.join(map(str, low))} not in the range x>={self.min}.", param, ctx)
        return numbers


class PerturbationSpec(click.ParamType):
    """One input perturbation ``TARGET:KIND:OCCUPANCY[:BURST_S[:SNR_DB]]``
    (:func:`dyadbench.protocol.perturbations.parse`), e.g. ``partner-motion:drop:0.3``."""

    name = "perturbation"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from dyadbench.errors import ConfigError  # noqa: PLC0415
        from dyadbench.protocol.perturbations import Perturbation, parse  # noqa: PLC0415

        if isinstance(value, Perturbation):
            return value
        try:
            return parse(value)
        except ConfigError as exc:
            self.fail(str(exc), param, ctx)


def torch_device(ctx: click.Context | None, param: click.Parameter | None, value: str) -> str:
    """Click callback for ``--device``: a device torch knows and this machine has (cpu, cuda, cuda:N)."""
    import torch  # noqa: PLC0415  (only when the option is parsed)

    try:
        device = torch.device(value)
    except (RuntimeError, ValueError):
        raise click.BadParameter(f"{value!r} is not a torch device (cpu, cuda, cuda:N)") from None
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise click.BadParameter(f"{value!r}: CUDA is not available here (torch {torch.__version__}); "
                                     "use --device cpu")
        if device.index is not None and device.index >= torch.cuda.device_count():
            raise click.BadParameter(f"{value!r}: this machine has {torch.cuda.device_count()} CUDA device(s)")
    elif device.type != "cpu":
        raise click.BadParameter(f"{value!r}: models run on cpu or cuda")
    return value


def deprecated_alias(alias: str, option: str, dest: str, **kwargs: Any) -> Callable:
    """A hidden option ``alias`` that still works as ``option`` (its value goes to the parameter ``dest``),
    with a note on stderr naming the spelling to use. Older spellings stay valid this way, so documented
    commands and the commands recorded in checkpoints run unchanged, while ``--help`` shows one name per
    concept (data root ``--data``, batch size ``--batch-size``, weights file ``--export``, resumable run
    folder ``--run-dir``). An option that an alias can supply is made required with :func:`required`."""

    def forward(ctx: click.Context, param: click.Parameter, value: Any) -> None:
        if value is not None:
            click.echo(f"note: {alias} is deprecated, use {option} (same meaning)", err=True)
            ctx.params[dest] = value

    return click.option(alias, f"{dest}_alias", default=None, hidden=True, expose_value=False, callback=forward,
                        **kwargs)


def required(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
    """Click callback of a required option that a :func:`deprecated_alias` may supply instead: click checks
    ``required=True`` before it sees an alias given on the command line, so the check is made here (the
    option is missing when neither it nor its alias was given)."""
    if value is None and ctx.params.get(param.name) is None:
        raise click.MissingParameter(ctx=ctx, param=param)
    return value


#: Registry tag (:data:`dyadbench.registry.MODELS`) of the models with classifier-free guidance.
GUIDANCE = "guidance"


def check_cfg_scale(models: Iterable[str], cfg_scale: float) -> None:
    """Refuse ``--cfg-scale`` other than 1 (off) for a registered model that does not declare guidance
    (registry tag :data:`GUIDANCE`): it would ignore the scale and record a variant that does not exist."""
    from dyadbench.registry import MODELS  # noqa: PLC0415

    if cfg_scale == 1.0:
        return
    without = [m for m in models if m in MODELS and GUIDANCE not in MODELS.get(m).tags]
    if without:
        guided = ", ".join(e.name for e in MODELS.entries.values() if GUIDANCE in e.tags)
        raise click.UsageError(f"--cfg-scale {cfg_scale:g}: {', '.join(without)} "
                               f"{'has' if len(without) == 1 else 'have'} no classifier-free guidance; only "
                               f"{guided} take --cfg-scale (leave it at 1 for the others)")
