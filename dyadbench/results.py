"""Typed result files of ``dyadbench eval``: one JSON per model / dataset / split / protocol setting.

A result records the model (name, version, weights digest, oracle flag, config), the data (dataset,
split, root, number of clips and scored items, content digest of the evaluated clips, and the train split
the model was fitted on: :mod:`dyadbench.protocol.train_split`), the protocol (streaming or offline,
turn length, context n, tail, history-agent policy, guidance scale, seed), the metric suite with mean
metrics raw and publication-scaled and the scale factors, per-clip raw metrics, coverage and exclusions,
timing (wall clock, mean per-turn latency), the environment (dyadbench, Python, NumPy, torch versions,
git commit) and the configuration the run was requested with
(:mod:`dyadbench.protocol.run_configuration`, what ``sweep`` compares before re-using a result), and each
column's standard error and bootstrap CI over dialogues (:mod:`dyadbench.uncertainty`; computed when
scoring, so kept without per-clip values) with the method that gave them. Fields
added later have defaults, so older files load. :func:`load_result` reads one back and rejects
malformed files with a message naming the file and the field; :func:`results_frame` loads many into a
long :class:`pandas.DataFrame`, the only input of the leaderboards.

``dyadbench score`` writes the same result for predictions made anywhere (:func:`external_result`):
protocol :data:`EXTERNAL` ("external predictions"), whose turn length, context, tail, history policy and
guidance scale dyadbench cannot know (None), the scoring seed as the seed, the model named by the user.
Files that ``score`` wrote before (``results.json``: the scores without model, data and protocol
records) load as such a result too (:func:`from_score_file`).
"""

from __future__ import annotations

import math
import platform
import subprocess
from dataclasses import MISSING, asdict, dataclass, field, fields
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Iterable, get_type_hints

import pandas as pd

from dyadbench import __version__, atomic, strict_json
from dyadbench.errors import InputError

SCHEMA = "dyadbench.eval-result/1"
#: Protocol name of a result scored from predictions on disk (``dyadbench score``), not run by dyadbench.
EXTERNAL = "external predictions"


@dataclass(frozen=True)
class ModelRecord:
    name: str
    version: str
    weights_digest: str | None
    weights_path: str | None
    oracle: bool
    layout: str
    config: dict


@dataclass(frozen=True)
class DataRecord:
    dataset: str
    split: str
    root: str | None
    clips: int  # dialogues (or sessions) run
    items: int  # evaluated directions (predictions written)
    digest: str | None = None  # content digest of the evaluated clips (dyadbench.provenance.split_digest)
    train: dict | None = None  # the train split the model opened: dataset, split, root, digest, clips, overlap


@dataclass(frozen=True)
class ProtocolRecord:
    name: str  # "streaming", "offline" or EXTERNAL (the settings below unknown: None)
    turn_seconds: float | None
    context: int | None
    tail: str | None
    history_agent: str | None
    cfg_scale: float | None
    seed: int  # the run's seed (EXTERNAL: the seed of the randomised metrics)
    speech_norm: str = "window"  # "clip": waveforms normalised with whole-clip statistics (not strictly causal)
    perturbations: str = ""  # input perturbations, "+"-joined (dyadbench.protocol.perturbations.describe)
    noise_scale: float | None = None  # motion-noise scale of a perturbed run (None: none used)


@dataclass(frozen=True)
class TimingRecord:
    wall_s: float
    model_s: float  # summed time inside the model's calls
    turns: int
    mean_turn_latency_s: float
    threads: int | None = None  # CPU threads per process (--threads); None: the libraries' default


@dataclass
class EvalResult:
    """One evaluation run (see module docstring). ``per_clip``: one dict of raw metrics per prediction."""

    model: ModelRecord
    data: DataRecord
    protocol: ProtocolRecord
    suite: str
    metrics: dict[str, float]
    scaled: dict[str, float]
    scaling: dict[str, float]
    per_clip: list[dict]
    timing: TimingRecord
    coverage: dict = field(default_factory=dict)
    excluded: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    predictions: str | None = None
    environment: dict = field(default_factory=dict)
    created_utc: str = ""
    configuration: dict | None = None  # dyadbench.protocol.run_configuration.requested_configuration
    uncertainty: dict = field(default_factory=dict)  # metric -> se, ci_low, ci_high (dyadbench.uncertainty)
    uncertainty_method: dict = field(default_factory=dict)  # method, resamples, level, seed, clusters
    schema: str = SCHEMA

    def to_dict(self) -> dict:
        d = asdict(self)
        columns = list(self.per_clip[0]) if self.per_clip else []
        d["per_clip"] = {"columns": columns, "rows": [[row.get(c) for c in columns] for row in self.per_clip]}
        return {"schema": d.pop("schema"), **d}

    def write(self, path: str | Path) -> Path:
        """Write atomically as JSON."""
        return atomic.write_json(path, self.to_dict())

    @classmethod
    def from_dict(cls, d: dict, source: str | Path = "result") -> "EvalResult":
        if not isinstance(d, dict):
            raise InputError(source, "not a JSON object")
        if d.get("schema") != SCHEMA:
            raise InputError(source, f"not a dyadbench eval result (schema {d.get('schema')!r}, expected {SCHEMA!r})")
        parts = {}
        for key, record in (("model", ModelRecord), ("data", DataRecord), ("protocol", ProtocolRecord),
                            ("timing", TimingRecord)):
            parts[key] = _record(record, d.get(key), source, key)
        for key in ("suite",):
            if not isinstance(d.get(key), str):
                raise InputError(source, f"field {key!r} missing or not a string")
        for key in ("metrics", "scaled", "scaling"):
            parts[key] = _numbers(d.get(key), source, key)
        per_clip = d.get("per_clip")
        if (not isinstance(per_clip, dict) or not isinstance(per_clip.get("columns"), list)
                or not isinstance(per_clip.get("rows"), list)):
            raise InputError(source, "field 'per_clip' must be {'columns': [...], 'rows': [[...], ...]}")
        columns = per_clip["columns"]
        rows = []
        for i, row in enumerate(per_clip["rows"]):
            if not isinstance(row, list) or len(row) != len(columns):
                raise InputError(source, f"per_clip row {i} does not have {len(columns)} values")
            rows.append({c: (math.nan if v is None and c != "clip" else v) for c, v in zip(columns, row)})
        return cls(suite=d["suite"], per_clip=rows, coverage=d.get("coverage") or {},
                   excluded=d.get("excluded") or [], notes=d.get("notes") or [],
                   predictions=d.get("predictions"), environment=d.get("environment") or {},
                   created_utc=d.get("created_utc", ""),
                   configuration=_optional_object(d, "configuration", source),
                   uncertainty=_optional_object(d, "uncertainty", source) or {},
                   uncertainty_method=_optional_object(d, "uncertainty_method", source) or {}, **parts)

    def per_clip_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.per_clip)

    @property
    def external(self) -> bool:
        """True for predictions scored by ``dyadbench score`` (made outside dyadbench's protocol)."""
        return self.protocol.name == EXTERNAL

    def flags(self) -> str:
        """Why the run must not be ranked besides being an oracle: ``train-overlap=N`` when its train split
        held N of the evaluated clips (run with --allow-train-overlap); empty otherwise."""
        overlap = (self.data.train or {}).get("overlap")
        return f"train-overlap={overlap}" if overlap else ""


def _record(record: type, value: object, source: str | Path, key: str):
    if not isinstance(value, dict):
        raise InputError(source, f"field {key!r} missing or not an object")
    missing = [f.name for f in fields(record) if f.name not in value and f.default is MISSING]
    if missing:
        raise InputError(source, f"field {key!r} lacks {', '.join(missing)}")
    names = [f.name for f in fields(record) if f.name in value]  # fields with defaults may be absent (older files)
    hints = get_type_hints(record)
    for name in names:
        allowed = _ALLOWED[hints[name]]
        v = value[name]
        if isinstance(v, bool) and bool not in allowed or not isinstance(v, allowed):
            raise InputError(source, f"{key}.{name} has the wrong type ({type(v).__name__}: {v!r})")
    return record(**{n: value[n] for n in names})


def _optional_object(d: dict, key: str, source: str | Path) -> dict | None:
    value = d.get(key)
    if value is not None and not isinstance(value, dict):
        raise InputError(source, f"field {key!r} is not an object")
    return value


_ALLOWED = {str: (str,), int: (int,), float: (int, float), bool: (bool,), dict: (dict,),
            str | None: (str, type(None)), int | None: (int, type(None)), dict | None: (dict, type(None)),
            float | None: (int, float, type(None))}


def _numbers(value: object, source: str | Path, key: str) -> dict[str, float]:
    if not isinstance(value, dict):
        raise InputError(source, f"field {key!r} missing or not an object")
    out = {}
    for k, v in value.items():
        if v is None:
            out[k] = math.nan
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[k] = float(v)
        else:
            raise InputError(source, f"{key}.{k} is not a number: {v!r}")
    return out


def load_result(path: str | Path) -> EvalResult:
    """Read one result file; InputError naming the file for unreadable or malformed content.

    Files are strict JSON with non-finite values recorded aside (:mod:`dyadbench.strict_json`); older
    files with bare ``NaN`` load to the same values.
    """
    path = Path(path)
    try:
        data = strict_json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, "result file not found") from None
    except (OSError, ValueError) as exc:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise InputError(path, f"not readable JSON ({exc})") from None
    if isinstance(data, dict) and "schema" not in data and {"suite", "metrics", "n_scored"} <= set(data):
        return from_score_file(data, path)
    return EvalResult.from_dict(data, path)


def external_result(report, *, model: str, dataset: str, split: str, root: str | None, predictions: str,
                    wall_s: float, seed: int, oracle: bool = False) -> EvalResult:
    """The typed result of predictions scored from disk (``dyadbench score``): ``report`` is the suite's
    :class:`~dyadbench.scoring.report.ScoreReport`, ``model`` the name the predictions are ranked under.

    ``clips`` counts the dialogues of the scored items (:func:`dyadbench.uncertainty.dialogue_of`), ``items``
    the scored predictions; the protocol is :data:`EXTERNAL` with the scoring seed; timing is the scoring
    wall time (no model ran: 0 turns); the score configuration is kept under ``model.config``. ``oracle``:
    the predictions copy the ground truth (a pipeline check, never ranked).
    """
    from dyadbench.uncertainty import dialogue_of  # noqa: PLC0415  (imports the gaze layout)

    rows = list(report.per_item)
    return EvalResult(
        model=ModelRecord(name=model, version=EXTERNAL, weights_digest=None, weights_path=None, oracle=oracle,
                          layout=_SUITE_LAYOUTS.get(report.suite, report.suite), config=dict(report.config)),
        data=DataRecord(dataset=dataset, split=split, root=root,
                        clips=len({dialogue_of(report.suite, str(r["clip"])) for r in rows}), items=len(rows)),
        protocol=ProtocolRecord(name=EXTERNAL, turn_seconds=None, context=None, tail=None, history_agent=None,
                                cfg_scale=None, seed=seed),
        suite=report.suite, metrics=dict(report.metrics), scaled=dict(report.scaled),
        scaling=dict(report.scaling), per_clip=rows, coverage=dict(report.coverage),
        excluded=list(report.excluded), notes=list(report.notes), predictions=predictions,
        timing=TimingRecord(wall_s=wall_s, model_s=0.0, turns=0, mean_turn_latency_s=0.0),
        environment=environment(), created_utc=utc_now(), uncertainty=dict(report.uncertainty),
        uncertainty_method=dict(report.uncertainty_method))


#: The motion layout (:data:`dyadbench.motion.LAYOUTS`) of each suite's predictions.
_SUITE_LAYOUTS = {"dualtalk": "flame56", "l2l": "flame56", "gaze": "gaze7", "react": "react25"}


def from_score_file(data: dict, path: Path) -> EvalResult:
    """A ``results.json`` written by ``dyadbench score`` before it wrote typed results, as an
    :func:`external_result`: the model is named by the file's folder, the data by the recorded ground
    truth (``config.gt``), per-clip values come from the ``per_clip.csv`` beside it (none when absent)."""
    for key in ("metrics", "config", "coverage"):
        if not isinstance(data.get(key), dict):
            raise InputError(path, f"field {key!r} missing or not an object (an old dyadbench score results.json?)")
    if not isinstance(data["suite"], str):
        raise InputError(path, "field 'suite' is not a string")
    config = data["config"]
    per_clip = path.parent / "per_clip.csv"
    rows = pd.read_csv(per_clip, dtype={"clip": str}).to_dict("records") if per_clip.is_file() else []
    scores = _OldScores(suite=data["suite"], metrics=_numbers(data["metrics"], path, "metrics"),
                        scaled=_numbers(data.get("scaled") or {}, path, "scaled"),
                        scaling=_numbers(data.get("scaling") or {}, path, "scaling"), config=config,
                        per_item=rows, coverage=data["coverage"], excluded=data.get("excluded") or [],
                        notes=data.get("notes") or [], uncertainty=data.get("uncertainty") or {},
                        uncertainty_method=data.get("uncertainty_method") or {})
    gt = str(config.get("gt", ""))
    result = external_result(scores, model=path.parent.name, dataset=data["suite"], split=Path(gt).name,
                             root=gt or None, predictions=str(config.get("pred", "")) or None,
                             wall_s=0.0, seed=int(config.get("seed", 0)))
    if not rows:  # items and clips as recorded (the per-clip file is gone)
        result.data = DataRecord(dataset=result.data.dataset, split=result.data.split, root=result.data.root,
                                 clips=int(result.uncertainty_method.get("clusters", data["n_scored"])),
                                 items=int(data["n_scored"]))
    result.environment = {"dyadbench": data.get("dyadbench_version")}
    result.created_utc = ""
    return result


@dataclass(frozen=True)
class _OldScores:
    """The fields of an old ``score`` results.json that :func:`external_result` reads."""

    suite: str
    metrics: dict
    scaled: dict
    scaling: dict
    config: dict
    per_item: list
    coverage: dict
    excluded: list
    notes: list
    uncertainty: dict
    uncertainty_method: dict


def result_files(paths: Iterable[str | Path]) -> list[Path]:
    """Expand folders to the ``*.json`` files below them (sorted); files are taken as given.

    A folder without any ``*.json`` file is an InputError naming it (nothing to build a table from).
    """
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(p.rglob("*.json"))
            if not found:
                raise InputError(p, "no result files (*.json) in this folder")
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise InputError(p, "no such result file or folder")
    return out


RESULT_COLUMNS = ("model", "oracle", "flags", "dataset", "split", "protocol", "context", "turn_seconds", "tail",
                  "history_agent", "cfg_scale", "speech_norm", "seed", "suite", "metric", "raw", "scaled", "scale",
                  "items", "clips", "digest", "weights_digest", "file")


def results_frame(paths: Iterable[str | Path]) -> pd.DataFrame:
    """Long table of mean metrics: one row per (result file, metric), columns :data:`RESULT_COLUMNS`.

    Runs with perturbed inputs are left out: they are the robustness axis (``dyadbench robustness``)."""
    rows = []
    for path in result_files(paths):
        r = load_result(path)
        if r.protocol.perturbations:
            continue
        for metric, raw in r.metrics.items():
            rows.append({"model": r.model.name, "oracle": bool(r.model.oracle), "flags": r.flags(),
                         "dataset": r.data.dataset,
                         "split": r.data.split, "protocol": r.protocol.name, "context": r.protocol.context,
                         "turn_seconds": r.protocol.turn_seconds, "tail": r.protocol.tail,
                         "history_agent": r.protocol.history_agent, "cfg_scale": r.protocol.cfg_scale,
                         "speech_norm": None if r.protocol.name == EXTERNAL else r.protocol.speech_norm,
                         "seed": r.protocol.seed, "suite": r.suite, "metric": metric, "raw": raw,
                         "scaled": r.scaled.get(metric, math.nan), "scale": r.scaling.get(metric, 1.0),
                         "items": r.data.items, "clips": r.data.clips, "digest": r.data.digest,
                         "weights_digest": r.model.weights_digest, "file": str(path)})
    return pd.DataFrame(rows, columns=list(RESULT_COLUMNS))


def environment() -> dict:
    """Versions recorded in every result (torch's version is read from its metadata, not imported)."""
    def version(dist: str) -> str | None:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return None

    return {"dyadbench": __version__, "python": platform.python_version(), "numpy": version("numpy"),
            "torch": version("torch"), "platform": platform.platform(), "git": git_commit()}


def git_commit() -> str | None:
    """Commit hash of the dyadbench checkout, or None when not run from a git checkout."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parent,
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None if out.returncode == 0 else None


def utc_now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
