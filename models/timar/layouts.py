"""The motion layouts TIMAR runs on: what it generates, which column flags valid frames, its loss groups.

A checkpoint's layout follows from its configuration's ``motion_dim`` (:func:`timar_layout`), so the
shipped 25-fps FLAME checkpoints load exactly as before:

- ``flame56`` (``motion_dim`` 56, 25 fps): every column generated; loss groups exp 50 | jaw 3 | pose 3.
- ``seamless`` (``motion_dim`` 165, 30 fps): the model generates the 165 feature columns of
  :data:`dyadbench.datasets.seamless.SEAMLESS` (expression 128 | head rotation 3 | the 34-d emotion stream:
  24 AUs, valence, arousal, 8 emotion scores) and not the last column, ``valid``; loss groups expression
  128 | head 3 | emotion 34 (equal weights, as exp | jaw | pose). Each predicted frame gets ``valid`` = 1.

**What a seamless model sees of invalid frames** (``valid`` = 0: the corpus's zero-filled 2-s blocks, which
the reader hands over as zeros). A user (partner) motion frame that is invalid becomes the learned null
token, the token guidance training uses for "no user input", so the zeros are never embedded as if they
were motion; an agent motion frame that is invalid is always [MASK] as input in training and never a loss
target (:meth:`models.timar.model.TimarModel.forward` with ``agent_valid``). The per-dimension motion
statistics come from valid frames only (:meth:`models.timar.data.WindowDataset.motion_statistics`).
"""

from __future__ import annotations

from dataclasses import dataclass

from dyadbench.errors import ConfigError


@dataclass(frozen=True)
class TimarLayout:
    name: str  # dyadbench motion layout (dyadbench.motion.LAYOUTS)
    motion_dim: int  # generated columns: the first motion_dim of the layout
    valid_column: int | None  # column of the 0/1 validity flag, None when the layout has none
    fps: float  # frame rate of the layout
    loss_groups: tuple[slice, ...]  # equally weighted MSE groups of the diffusion loss

    @property
    def dim(self) -> int:
        """Columns of the layout (generated + validity)."""
        return self.motion_dim + (self.valid_column is not None)


FLAME56 = TimarLayout("flame56", 56, None, 25.0, (slice(0, 50), slice(50, 53), slice(53, 56)))
SEAMLESS = TimarLayout("seamless", 165, 165, 30.0, (slice(0, 128), slice(128, 131), slice(131, 165)))
TIMAR_LAYOUTS = {layout.name: layout for layout in (FLAME56, SEAMLESS)}
_BY_DIM = {layout.motion_dim: layout for layout in TIMAR_LAYOUTS.values()}


def timar_layout(motion_dim: int) -> TimarLayout:
    """The layout of a configuration with ``motion_dim`` generated columns."""
    if motion_dim not in _BY_DIM:
        raise ConfigError(f"TIMAR has no motion layout of {motion_dim} generated dims "
                          f"(known: {', '.join(f'{l.name} {l.motion_dim}' for l in TIMAR_LAYOUTS.values())})")
    return _BY_DIM[motion_dim]


def layout_named(name: str) -> TimarLayout:
    """The TIMAR layout of the dyadbench motion layout ``name``, or a ConfigError listing those TIMAR runs on."""
    if name not in TIMAR_LAYOUTS:
        raise ConfigError(f"TIMAR runs on the motion layouts {', '.join(TIMAR_LAYOUTS)}, not {name!r}")
    return TIMAR_LAYOUTS[name]


def configure_for(cfg, layout: TimarLayout):
    """``cfg`` (a :class:`models.timar.config.TimarConfig`) generating ``layout``'s columns with 1-s turns at
    its frame rate (frames per turn = fps · samples_per_turn / 16 kHz); unchanged for ``flame56``."""
    from dataclasses import replace  # noqa: PLC0415

    frames = layout.fps * cfg.samples_per_turn / 16_000
    if frames != int(frames):
        raise ConfigError(f"{cfg.samples_per_turn} samples per turn at 16 kHz are not a whole number of frames at "
                          f"{layout.fps:g} fps")
    return replace(cfg, motion_dim=layout.motion_dim, frames_per_turn=int(frames))
