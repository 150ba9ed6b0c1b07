"""The gaze–head suite (StyGazeTalk, Tables 2–3): score predicted 7-angle tracks against ground truth.

Per prediction (the first ``skip_frames`` frames, the models' seed window, are excluded for every
model): MAE, Vel, Vel_abs, MEE, MEE_frame for all / gaze / head; per-sequence FixRatio, CompScore
and SimWithGT; BAS against the session's own speech onsets in both directions, for all / gaze / head.
Over the split: error metrics are the mean over sequences; FixRatio pools frame counts and CompScore
pools velocity frames over all sequences, for the predictions and the ground truth; ``sim_gt`` is
computed once from those aggregates (the paper's SimScore) and ``sim_gt_seq`` is the mean of the
per-sequence values. BAS is also computed against a fixed derangement of the sequences' speech
(``*_shuffled``, seeded by ``seed``) and reported as the difference (``*_delta``); the ground truth's
own BAS is reported beside it (``gt_bas_*``). Sequences whose BAS is undefined (no beats) are left out
of its mean and counted in the notes.

The style cosine error needs a frozen style encoder (:class:`dyadbench.metrics.gaze.StyleEncoder`):
pass it as ``style_encoder``; without one ``style_ce`` is not reported. A model's run
(:func:`model_options`) uses the evaluator registered as :data:`STYLE_EVALUATOR`.

Uncertainty (:mod:`dyadbench.uncertainty`, resampling sessions): the means over sequences get a
cluster-robust standard error and a bootstrap CI; the pooled columns (fix/saccade ratio, CompScore, for
prediction and ground truth, and ``sim_gt``) are recomputed from the resampled frame counts
(:func:`pooled_statistics`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from dyadbench import uncertainty
from dyadbench.arrays import check_motion
from dyadbench.datasets.gaze import SessionFile, open_split
from dyadbench.errors import InputError
from dyadbench.metrics import beats, gaze
from dyadbench.metrics.fixations import fixation_counts
from dyadbench.motion import FPS, GAZE7
from dyadbench.registry import EVALUATORS
from dyadbench.scoring import policy
from dyadbench.scoring.parallel import map_items
from dyadbench.scoring.predictions import open_predictions
from dyadbench.scoring.report import ScoreItem, ScoreReport
from dyadbench.seeding import rng

SUITE = "gaze"
SEED_FRAMES = 50  # M = 2 s: StyGazeTalk's seed window, excluded for every model
#: the frozen, versioned style encoder every model's ``style_ce`` is computed with (a name in
#: :data:`dyadbench.registry.EVALUATORS`; the reference model that provides it is imported only when used)
STYLE_EVALUATOR = "stygazetalk-style"
ERROR_METRICS = {"mae": gaze.mae, "vel": gaze.vel, "vel_abs": gaze.vel_abs, "mee": gaze.mee,
                 "mee_frame": gaze.mee_frame}
BAS_GROUPS = ("all", "gaze", "head")


@dataclass(frozen=True)
class GazeSuiteConfig:
    """Every decision of the suite, recorded in results (defaults reproduce the paper's reading)."""

    skip_frames: int = SEED_FRAMES
    idt_threshold_deg: float = 3.5
    idt_min_frames: int = 3
    idt_eyes: str = "pooled"  # or "cyclopean"
    idt_include_breaking_sample: bool = False  # True: pymovements' variant
    comp_velocity_unit: str = "deg_per_frame"  # or "deg_per_s"
    comp_include_roll: bool = False  # True: roll counts in the -|h| branch
    bas_order_s: float = beats.ORDER_S
    bas_sigma_s: float = beats.SIGMA_S
    bas_min_speed: float = 0.0

    def idt(self) -> dict:
        return {"threshold_deg": self.idt_threshold_deg, "min_frames": self.idt_min_frames,
                "eyes": self.idt_eyes, "include_breaking_sample": self.idt_include_breaking_sample}


NOT_METRICS = {"clip", "frames", "truncated", "speech_onsets"}


@dataclass(frozen=True)
class _Task:
    item: ScoreItem
    config: GazeSuiteConfig


def _check(item: ScoreItem, skip: int) -> tuple[str | None, list[str | None]]:
    """The bad-input policy (:mod:`dyadbench.scoring.policy`) for one item: errors are raised; returns the
    reason it is excluded (None: scored) and the magnitude warnings."""
    if item.fps != FPS:
        raise InputError(item.stem, f"the gaze suite scores {FPS:g}-fps motion, got {item.fps:g} fps")
    gt = check_motion(item.gt, item.gt_name, GAZE7.dim)
    pred = check_motion(item.pred, item.pred_name, GAZE7.dim, finite=False)
    warnings = [policy.magnitude_warning(gt, item.gt_name, GAZE7)]
    reason = policy.exclusion(pred, item.pred_name)
    n = min(len(pred), len(gt))
    if reason is None and n - skip < 3:
        reason = policy.too_short(item.pred_name, n, skip + 3, f"common frames ({skip} seed frames are excluded)")
    if reason is None:
        warnings.append(policy.magnitude_warning(pred, item.pred_name, GAZE7))
    return reason, warnings


def _prepare(item: ScoreItem, skip: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, int]:
    """Pred/gt (checked by :func:`_check`) cut to a common length with the seed frames removed; audio cut
    alike."""
    pred, gt = np.asarray(item.pred, dtype=np.float64), np.asarray(item.gt, dtype=np.float64)
    n = min(len(pred), len(gt))
    audio = None
    if item.audio is not None:
        hop = int(round(item.sample_rate / item.fps))
        audio = np.pad(np.asarray(item.audio, dtype=np.float32), (0, max(0, n * hop - len(item.audio))))[:n * hop]
    return pred[skip:n], gt[skip:n], audio, n


def _score_item(task: _Task) -> dict:
    item, cfg = task.item, task.config
    pred, gt, audio, n_common = _prepare(item, cfg.skip_frames)
    row: dict = {"clip": item.stem, "frames": len(pred),
                 "truncated": int(max(len(item.pred), len(item.gt)) - n_common)}
    for group in gaze.GROUPS:
        for name, fn in ERROR_METRICS.items():
            row[f"{name}_{group}"] = fn(pred, gt, group)
    counts = {}
    for who, motion in (("pred", pred), ("gt", gt)):
        labels = gaze.fixation_labels(motion, name=f"{item.stem} ({who})", **cfg.idt())
        counts[f"{who}_fix"], counts[f"{who}_sac"] = fixation_counts(labels)
        comp = gaze.compensation_frames(motion, velocity_unit=cfg.comp_velocity_unit, fps=item.fps,
                                        include_roll=cfg.comp_include_roll)
        counts[f"{who}_comp_sum"], counts[f"{who}_comp_n"] = float(comp.sum()), len(comp)
    fix = counts["pred_fix"] / max(1, counts["pred_fix"] + counts["pred_sac"])
    gt_fix = counts["gt_fix"] / max(1, counts["gt_fix"] + counts["gt_sac"])
    comp_p = counts["pred_comp_sum"] / counts["pred_comp_n"]
    comp_g = counts["gt_comp_sum"] / counts["gt_comp_n"]
    row.update(fix_ratio=fix, comp_score=comp_p, gt_fix_ratio=gt_fix, gt_comp_score=comp_g,
               sim_gt=gaze.sim_with_gt(gt_fix, comp_g, fix, comp_p))
    beat_sets = {}
    if audio is not None:
        onsets = beats.speech_onsets(audio, item.sample_rate, item.fps)
        beat_sets["onsets"] = onsets[onsets >= cfg.skip_frames / item.fps] - cfg.skip_frames / item.fps
        for group in BAS_GROUPS:
            for who, motion in (("pred", pred), ("gt", gt)):
                beat_sets[f"{who}_{group}"] = beats.motion_beats(motion, group, fps=item.fps, order_s=cfg.bas_order_s,
                                                                 min_speed=cfg.bas_min_speed)
    return {"row": row, "counts": counts, "beats": beat_sets}


def derangement(n: int, seed: int) -> np.ndarray | None:
    """A seeded permutation of range(n) without fixed points (None when n < 2)."""
    if n < 2:
        return None
    r = rng(seed, "gaze-bas-derangement", n)
    while True:
        perm = r.permutation(n)
        if not np.any(perm == np.arange(n)):
            return perm


def _add_bas(results: list[dict], cfg: GazeSuiteConfig, seed: int, notes: list[str]) -> None:
    """BAS per item (matched, shuffled, delta; m2a and a2m; prediction and GT), in place."""
    with_audio = [r for r in results if r["beats"]]
    if len(with_audio) < len(results):
        notes.append(f"BAS: {len(results) - len(with_audio)} predictions have no speech; BAS not computed for them")
    perm = derangement(len(with_audio), seed)
    if with_audio and perm is None:
        notes.append("BAS: shuffled-speech reference needs at least 2 sequences; bas_shuffled/bas_delta are NaN")
    empty: dict[str, int] = {}
    for i, res in enumerate(with_audio):
        b, row = res["beats"], res["row"]
        other = with_audio[perm[i]]["beats"]["onsets"] if perm is not None else None
        for group in BAS_GROUPS:
            for who, prefix in (("pred", ""), ("gt", "gt_")):
                mb = b[f"{who}_{group}"]
                reason = beats.empty_reason(len(mb), len(b["onsets"]))
                if reason and who == "pred":
                    row[f"bas_note_{group}"] = reason
                    key = f"{group}: {reason}"
                    empty[key] = empty.get(key, 0) + 1
                for direction, tag in (("m2a", ""), ("a2m", "_a2m")):
                    kw = {"sigma_s": cfg.bas_sigma_s, "direction": direction}
                    matched = beats.beat_alignment(mb, b["onsets"], **kw)
                    shuffled = beats.beat_alignment(mb, other, **kw) if other is not None else float("nan")
                    row[f"{prefix}bas{tag}_{group}"] = matched
                    row[f"{prefix}bas{tag}_shuffled_{group}"] = shuffled
                    row[f"{prefix}bas{tag}_delta_{group}"] = matched - shuffled
            row[f"motion_beats_{group}"] = len(b[f"pred_{group}"])
        row["speech_onsets"] = len(b["onsets"])
    for key, count in sorted(empty.items()):
        notes.append(f"BAS {key}: NaN for {count} of {len(with_audio)} sequences (left out of the mean)")


def _add_style(results: list[dict], items: dict[str, ScoreItem], cfg: GazeSuiteConfig, encoder) -> None:
    for res in results:
        item = items[res["row"]["clip"]]
        n = min(len(item.pred), len(item.gt))
        gt_w = gaze.sliding_windows(np.asarray(item.gt[cfg.skip_frames:n], np.float64), encoder.window, encoder.hop)
        pred_w = gaze.sliding_windows(np.asarray(item.pred[cfg.skip_frames:n], np.float64), encoder.window,
                                      encoder.hop)
        res["row"]["style_ce"] = (gaze.style_cosine_error(encoder(gt_w), encoder(pred_w)) if len(gt_w)
                                  else float("nan"))


def pooled_statistics(counts: list[dict]) -> dict[str, uncertainty.SetStatistic]:
    """The split-level columns as functions of sequence weights w (B, N) (:mod:`dyadbench.uncertainty`;
    all ones: the split's values): FixRatio = Σ w·fix / max(1, Σ w·(fix + sac)) over pooled frame counts,
    CompScore = Σ w·comp_sum / Σ w·comp_n over pooled velocity frames, for the prediction and the ground
    truth, and SimWithGT from those aggregates (:func:`dyadbench.metrics.gaze.sim_with_gt`)."""
    total = {k: np.array([c[k] for c in counts], dtype=np.float64) for k in counts[0]}

    def fix(who: str) -> uncertainty.SetStatistic:
        return lambda w: (w @ total[f"{who}_fix"]) / np.maximum(1.0, w @ (total[f"{who}_fix"] + total[f"{who}_sac"]))

    def comp(who: str) -> uncertainty.SetStatistic:
        return uncertainty.ratio(total[f"{who}_comp_sum"], total[f"{who}_comp_n"])

    def saccade(who: str) -> uncertainty.SetStatistic:
        return lambda w: 1.0 - fix(who)(w)

    return {"fix_ratio": fix("pred"), "saccade_ratio": saccade("pred"), "comp_score": comp("pred"),
            "gt_fix_ratio": fix("gt"), "gt_saccade_ratio": saccade("gt"), "gt_comp_score": comp("gt"),
            "sim_gt": lambda w: gaze.sim_with_gt(fix("gt")(w), comp("gt")(w), fix("pred")(w), comp("pred")(w))}


def _nanmean(values: list[float]) -> float:
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    return float(arr.mean()) if arr.size else float("nan")


def score_arrays(items: list[ScoreItem], *, jobs: int = 1, seed: int = 0, config: GazeSuiteConfig | None = None,
                 style_encoder: gaze.StyleEncoder | None = None) -> ScoreReport:
    """Score in-memory predictions with the gaze–head suite (see the module docstring).

    ``style_encoder``: a frozen :class:`~dyadbench.metrics.gaze.StyleEncoder` for ``style_ce``
    (its ``digest`` is recorded); None leaves ``style_ce`` out. ``seed`` fixes the shuffled-speech
    derangement of the BAS reference.
    """
    return _score(items, jobs=jobs, seed=seed, config=config, style_encoder=style_encoder,
                  coverage={"expected": len(items), "missing": [], "extra": []}, inputs={"pred": None, "gt": None},
                  warnings=[])


def model_options(info) -> dict:
    """:func:`score_arrays` keyword arguments for a model's run: skip at least the model's seed window
    (``ModelInfo.seed_frames``, never less than :data:`SEED_FRAMES`) and score ``style_ce`` with the
    :data:`STYLE_EVALUATOR`, the same network for every model."""
    return {"config": GazeSuiteConfig(skip_frames=max(SEED_FRAMES, info.seed_frames)),
            "style_encoder": EVALUATORS.load(STYLE_EVALUATOR)()}


def _score(items: list[ScoreItem], *, jobs: int, seed: int, config: GazeSuiteConfig | None,
           style_encoder: gaze.StyleEncoder | None, coverage: dict, inputs: dict,
           warnings: list[str | None]) -> ScoreReport:
    """Score ``items`` (see :func:`score_arrays`); ``coverage`` gives expected, missing and extra,
    ``warnings`` the ground-truth files' magnitude warnings, ``inputs`` names pred and gt."""
    cfg = config or GazeSuiteConfig()
    stems = [it.stem for it in items]
    if len(set(stems)) != len(stems):
        raise InputError("predictions", "two items share a stem")
    tasks, excluded = [], []
    for it in items:
        reason, found = _check(it, cfg.skip_frames)
        warnings = warnings + found
        if reason is None:
            tasks.append(_Task(it, cfg))
        else:
            excluded.append({"clip": it.stem, "reason": reason})
    if not tasks:
        raise policy.nothing_scored(inputs["pred"], excluded, coverage["extra"], stems + coverage["missing"],
                                    warnings)
    results = list(map_items(_score_item, tasks, jobs=jobs, desc="gaze suite"))
    notes = policy.warning_notes(warnings) + policy.extra_notes(coverage["extra"], stems + coverage["missing"])
    _add_bas(results, cfg, seed, notes)
    if style_encoder is not None:
        _add_style(results, {it.stem: it for it in items}, cfg, style_encoder)
    else:
        notes.append("style_ce not computed: it needs a frozen style encoder (score_arrays(..., style_encoder=...))")
    truncated = sum(1 for r in results if r["row"]["truncated"])
    if truncated:
        notes.append(f"{truncated} predictions differ in length from their ground truth; scored on the common frames")
    per_item = [r["row"] for r in results]
    for row in per_item:
        row["sim_gt_seq"] = row.pop("sim_gt")
    keys = dict.fromkeys(k for row in per_item for k in row
                         if k not in NOT_METRICS and not k.startswith(("motion_beats_", "bas_note_")))
    metrics = {k: _nanmean([row.get(k, float("nan")) for row in per_item]) for k in keys}
    pooled = pooled_statistics([r["counts"] for r in results])
    metrics.update({k: float(fn(np.ones((1, len(results))))[0]) for k, fn in pooled.items()})
    spread, method = uncertainty.estimate(SUITE, per_item, [k for k in metrics if k not in pooled], seed=seed,
                                          set_level=pooled)
    config_dict = {**asdict(cfg), "seed": seed, "fps": FPS, "velocity": "first difference, deg/frame",
                   "aggregation": "error metrics: mean over sequences; fix_ratio/comp_score: pooled frames; "
                                  "sim_gt: from split-level aggregates",
                   "style_encoder": getattr(style_encoder, "digest", None),
                   "higher_is_better": gaze.COLUMNS.directions(metrics)}
    return ScoreReport(suite=SUITE, metrics=metrics, per_item=per_item, excluded=excluded,
                       coverage={"expected": coverage["expected"], "scored": len(per_item),
                                 "missing": coverage["missing"], "extra": coverage["extra"]},
                       config=config_dict, notes=notes, columns=gaze.COLUMNS.table_columns(set(metrics)),
                       uncertainty=spread, uncertainty_method=method)


def score_paths(pred: str | Path, gt: str | Path, *, split: str | None = None, jobs: int = 1,
                seed: int = 0, config: GazeSuiteConfig | None = None,
                style_encoder: gaze.StyleEncoder | None = None) -> ScoreReport:
    """Score predictions on disk against a gaze–head root or split folder (:mod:`dyadbench.datasets.gaze`).

    ``pred``: a folder of ``<clip>_subject.npy`` (T, 7) degree arrays (``<clip>.npy`` is accepted too), or
    one ``.npz`` keyed by those stems. Missing predictions are listed in the coverage; files matching no
    ground-truth clip are counted as extra.
    """
    source = open_split(Path(gt), split)
    files = open_predictions(pred)
    items, missing, used, sessions = [], [], set(), {}
    for clip in source:
        stem = clip.agent_ids()[0]
        session = clip.meta["session"]
        sessions[session] = source.session_path(session)
        name = stem if stem in files else clip.clip_id if clip.clip_id in files else None
        if name is None:
            missing.append(stem)
            continue
        used.add(name)
        p = clip.participants[0]
        items.append(ScoreItem(stem=stem, pred=files[name].load(GAZE7.dim), gt=p.motion, audio=p.audio,
                               identity=p.identity, fps=clip.fps, sample_rate=clip.sample_rate,
                               pred_source=files[name].name, gt_source=f"{sessions[session]}[motion]"))
    # the sessions as stored: frames beyond the 40° rule are dropped before scoring, but named here
    warnings = [policy.magnitude_warning(_tracked(source.session(s)), f"{path}[motion]", GAZE7)
                for s, path in sessions.items()]
    report = _score(items, jobs=jobs, seed=seed, config=config, style_encoder=style_encoder,
                    coverage={"expected": len(source), "missing": missing, "extra": sorted(set(files) - used)},
                    inputs={"pred": str(pred), "gt": str(gt)}, warnings=warnings)
    report.config["ground_truth"] = source.describe()
    return report


def _tracked(session: SessionFile) -> np.ndarray:
    """A session's motion in the frames not marked as tracker loss."""
    return session.motion if session.valid is None else session.motion[session.valid]
