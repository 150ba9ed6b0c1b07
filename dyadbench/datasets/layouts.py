"""On-disk layouts ``dyadbench data`` can write (synthetic corpus), validate and describe.

Each entry names three functions, imported lazily:

- ``writer(out: Path, *, split: str, clips: int | None, seed: int, jobs: int) -> dict`` writes a
  synthetic split in that layout and returns a summary;
- ``validator(folder: Path) -> ValidationReport`` (:mod:`dyadbench.datasets.validation`);
- ``info(folder: Path) -> dict`` split statistics.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

from dyadbench.errors import ConfigError


@dataclass(frozen=True)
class Layout:
    name: str
    writer: str
    validator: str
    info: str
    summary: str

    def _load(self, target: str) -> Callable[..., Any]:
        module, _, attr = target.partition(":")
        return getattr(importlib.import_module(module), attr)

    def write(self, *args: Any, **kwargs: Any) -> Any:
        return self._load(self.writer)(*args, **kwargs)

    def validate(self, *args: Any, **kwargs: Any) -> Any:
        return self._load(self.validator)(*args, **kwargs)

    def describe(self, *args: Any, **kwargs: Any) -> Any:
        return self._load(self.info)(*args, **kwargs)


LAYOUTS: dict[str, Layout] = {
    "dualtalk": Layout("dualtalk", "dyadbench.synth.writers:write_dualtalk_split",
                       "dyadbench.datasets.dualtalk:validate_folder", "dyadbench.datasets.dualtalk:folder_info",
                       "flat <clip>_speaker{1,2}.{wav,npz} (exp, pose=[rot|jaw]) at 25 fps / 16 kHz"),
    "react": Layout("react", "dyadbench.synth.react_writer:write_react_split",
                    "dyadbench.datasets.react:validate_folder", "dyadbench.datasets.react:folder_info",
                    "REACT root: split csv, Emotion csv (25-d), 3D_FV npy, neighbour matrix"),
    "l2l": Layout("l2l", "dyadbench.synth.l2l_writer:write_l2l_split",
                  "dyadbench.datasets.l2l:validate_folder", "dyadbench.datasets.l2l:folder_info",
                  "Learning2Listen <host>/{train,test}/p{0,1}_*_clean_deca.npy arrays"),
    "seamless": Layout("seamless", "dyadbench.synth.seamless_writer:write_seamless_split",
                       "dyadbench.datasets.seamless:validate_folder", "dyadbench.datasets.seamless:folder_info",
                       "Seamless Interaction <label>/<split>/: V_S_I_P participant npz + 48 kHz wav (and the "
                       "per-modality layout), 30 Hz movement features with 2-s invalid blocks"),
    "gaze": Layout("gaze", "dyadbench.synth.gaze_writer:write_gaze_split",
                   "dyadbench.datasets.gaze:validate_folder", "dyadbench.datasets.gaze:folder_info",
                   "dyadbench gaze-head sessions: <session>.npz (7 angles, deg) + <session>.wav + speaker id"),
}


def get_layout(name: str) -> Layout:
    if name not in LAYOUTS:
        raise ConfigError(f"unknown layout {name!r} (known: {', '.join(LAYOUTS)})")
    return LAYOUTS[name]
