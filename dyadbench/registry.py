"""Name -> "module:attr" registries for models, datasets and metric suites.

Entries are imported only when used, so listing them (``dyadbench models``) never imports torch.
Duplicate names are rejected; an unknown name gets close matches suggested.
"""

from __future__ import annotations

import difflib
import importlib
from dataclasses import dataclass, field
from typing import Any

from dyadbench.errors import ConfigError


@dataclass(frozen=True)
class Entry:
    name: str
    target: str  # "package.module:attribute"
    summary: str
    tags: tuple[str, ...] = ()

    def load(self) -> Any:
        module_name, _, attr = self.target.partition(":")
        module = importlib.import_module(module_name)
        return getattr(module, attr)


@dataclass
class Registry:
    kind: str
    entries: dict[str, Entry] = field(default_factory=dict)

    def add(self, name: str, target: str, summary: str, tags: tuple[str, ...] = ()) -> None:
        if name in self.entries:
            raise ConfigError(f"duplicate {self.kind} name {name!r}")
        self.entries[name] = Entry(name, target, summary, tags)

    def get(self, name: str) -> Entry:
        try:
            return self.entries[name]
        except KeyError:
            close = difflib.get_close_matches(name, list(self.entries), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            known = ", ".join(sorted(self.entries))
            raise ConfigError(f"unknown {self.kind} {name!r}{hint} (known: {known})") from None

    def load(self, name: str) -> Any:
        return self.get(name).load()

    def names(self) -> list[str]:
        return list(self.entries)

    def __contains__(self, name: str) -> bool:
        return name in self.entries


MODELS = Registry("model")
DATASETS = Registry("dataset")
# The embedded corpus a run uses when it names neither --dataset nor --data.
DEFAULT_EMBEDDED = "synthetic-v2"
# The embedded corpora's generator versions: tables and figures name each corpus with its version.
EMBEDDED_VERSIONS = {"synthetic": 1, "synthetic-v2": 2}


def dataset_label(name: str) -> str:
    """How tables and figures name a dataset: an embedded corpus with its version, the default one marked
    (``synthetic (v1)``, ``synthetic-v2 (v2, default)``); any other dataset by its name."""
    version = EMBEDDED_VERSIONS.get(name)
    if version is None:
        return name
    return f"{name} (v{version}{', default' if name == DEFAULT_EMBEDDED else ''})"


def dataset_order(name: str) -> tuple[bool, str]:
    """Sort key of datasets in tables: the default embedded corpus first, then by name."""
    return name != DEFAULT_EMBEDDED, name
SUITES = Registry("metric suite")
EVALUATORS = Registry("frozen evaluator")

# --- metric suites: "module:function" scoring files on disk (see dyadbench.scoring) ---------------
SUITES.add("dualtalk", "dyadbench.scoring.dualtalk:score_paths",
           "DualTalk/TIMAR suite: FD, P-FD, MSE, SID, rPCC, STS, Var, Div per exp/jaw/pose")
SUITES.add("react", "dyadbench.scoring.react:score_paths",
           "REACT 2023/2024 suite: FRCorr, FRDist, FRDiv, FRVar, FRDvs, FRSyn")
SUITES.add("l2l", "dyadbench.scoring.l2l:score_paths",
           "Learning2Listen-line suite: L2, FD, P-FD, Var, SI, rPCC")
SUITES.add("seamless", "dyadbench.scoring.seamless:score_paths",
           "Seamless Interaction suite: FD, P-FD, MSE, SID, rPCC, Var, Div per expression/head(/gaze); FRCorr, "
           "FRDist, FRVar, FRSyn on the 34-d emotion stream; invalid frames excluded")
SUITES.add("gaze", "dyadbench.scoring.gaze:score_paths",
           "Gaze-head suite (StyGazeTalk): MAE, Vel, MEE, FixRatio, CompScore, SimWithGT, BAS")

# --- frozen evaluators: loaders ``load() -> network`` a suite scores every model with, by name ----------
EVALUATORS.add("stygazetalk-style", "models.stygazetalk.evaluator:load_style_evaluator",
               "Frozen, versioned StyGazeTalk SE-64 style encoder: the gaze suite's style_ce")

# --- datasets: factories ``open_split(root: Path | None, split: str | None) -> ClipSource``; split None:
# the split folder ``root`` itself (ClipSource.single_split), else the dataset's test split ----------
DATASETS.add("synthetic", "dyadbench.datasets.synthetic:open_split",
             "Embedded synthetic dyadic-conversation corpus v1 (generated on first use, cached); the default before v2")
DATASETS.add("synthetic-v2", "dyadbench.datasets.synthetic:open_split_v2",
             "Embedded synthetic corpus v2: v1 plus conversational dynamics over many seconds (shared mood, "
             "entrainment, listener engagement, nod excitation); generated on first use, cached. Default.")
DATASETS.add("dualtalk", "dyadbench.datasets.dualtalk:open_split",
             "DualTalk folders train/ test/ ood/ with <clip>_speaker{1,2}.{wav,npz}")
DATASETS.add("l2l", "dyadbench.datasets.l2l:open_split",
             "Learning2Listen per-host train/ test/ arrays (64-frame windows, 30 fps, speaker mel rows; "
             "the listener is generated and scored with the l2l suite)")
DATASETS.add("react", "dyadbench.datasets.react:open_split",
             "REACT 2023/2024 layout: split csv, Emotion csv, 3D_FV npy, neighbour matrix")
DATASETS.add("seamless", "dyadbench.datasets.seamless:open_split",
             "Seamless Interaction <label>/<split>/ participant bundles (npz+wav or per-modality), 30 Hz movement "
             "features (expression 128, head 3, emotion 34, validity), 48 kHz speech read at 16 kHz")
DATASETS.add("seamless-gaze", "dyadbench.datasets.seamless:open_split_gaze",
             "Seamless Interaction with the 2-d gaze encoding in the motion layout")
DATASETS.add("gaze", "dyadbench.datasets.gaze:open_split",
             "dyadbench gaze-head session layout (7 angles in degrees at 25 fps + 16 kHz speech)")
DATASETS.add("synthetic-gaze", "dyadbench.datasets.synthetic_gaze:open_synthetic_split",
             "Embedded synthetic gaze-head sessions (generated on first use, cached)")

# --- models: factories ``build(options: ModelOptions) -> StreamingModel | OfflineModel`` -------------
MODELS.add("zero", "baselines.trivial:build_zero", "Zero motion (all coefficients 0)", ("baseline",))
MODELS.add("mean-frame", "baselines.trivial:build_mean_frame", "Mean frame of the train split", ("baseline",))
MODELS.add("median-frame", "baselines.trivial:build_median_frame", "Median frame of the train split",
           ("baseline",))
MODELS.add("random", "baselines.trivial:build_random",
           "Gaussian frames with the train mean and covariance (seeded)", ("baseline",))
MODELS.add("mime", "baselines.partner:build_mime", "Copy the partner's current motion", ("baseline",))
MODELS.add("lagged-mirror", "baselines.partner:build_lagged_mirror",
           "Partner's motion delayed by a fixed lag", ("baseline",))
MODELS.add("nn-retrieval", "baselines.retrieval:build_nn_retrieval",
           "Agent motion of the most similar train turn by partner features", ("baseline",))
MODELS.add("oracle", "baselines.oracle:build_oracle",
           "Ground-truth copy (ORACLE: reads the agent's ground truth; never ranked)", ("oracle",))
MODELS.add("gaze-static", "baselines.gaze:build_static", "Gaze straight ahead, head still (gaze-head)",
           ("baseline", "gaze"))
MODELS.add("gaze-headcopy", "baselines.gaze:build_headcopy",
           "Eyes follow the ground-truth head direction (ORACLE head; gaze-head; never ranked)", ("oracle", "gaze"))
MODELS.add("timar", "models.timar.registry:build_timar",
           "TIMAR: turn-level interleaved masked autoregression with a diffusion head",
           ("reference", "guidance"))
MODELS.add("timar-stream", "models.timar.registry:build_timar_stream",
           "TIMAR streaming-native variant: per-turn sliding band, exact KV cache",
           ("reference", "guidance"))
MODELS.add("dualtalk", "models.dualtalk.registry:build_dualtalk",
           "DualTalk under progressive-context streaming (window of min(t, n) + 1 turns, current turn kept)",
           ("reference",))
MODELS.add("dualtalk-offline", "models.dualtalk.registry:build_dualtalk_offline",
           "DualTalk over the whole clip at once (the published DualTalk protocol; recorded offline)",
           ("reference",))
MODELS.add("sfms", "models.sfms.registry:build_sfms",
           "SFMS: sparse keyframe tokenizer + listening-head predictor", ("reference",))
MODELS.add("sfms-channel", "models.sfms.registry:build_sfms_channel",
           "SFMS with per-channel keyframe allocation (the paper's default; shipped for corpus v2)", ("reference",))
MODELS.add("stygazetalk", "models.stygazetalk.registry:build_stygazetalk",
           "StyGazeTalk: style-aware gaze-head generation from speech", ("reference", "gaze"))
