"""StyGazeTalk's gaze–head metrics: MAE, Vel, MEE per group, FixRatio, CompScore, SimWithGT, style cosine error.

Motion is the 7-angle gaze–head layout in degrees at 25 fps (:data:`dyadbench.motion.GAZE7`):
``[head_pitch, head_yaw, head_roll, L_pitch, L_yaw, R_pitch, R_yaw]``. Groups: ``all`` (7 dims), ``gaze``
(dims 3–6), ``head`` (dims 0–2). Velocities are first differences in **degrees per frame** (the unit
in which the paper's CompScore magnitudes are plausible); multiply by fps for °/s.

Every function here is pure (arrays in, numbers out). :data:`METRICS` declares, per metric, whether
higher is better (``None`` = "closer to the ground truth's value is better") and its unit.
The beat alignment score lives in :mod:`dyadbench.metrics.beats`, I-DT in :mod:`dyadbench.metrics.fixations`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dyadbench.errors import InputError
from dyadbench.metrics.columns import ColumnSpec, SuiteColumns
from dyadbench.metrics.fixations import (DISPERSION_THRESHOLD_DEG, MIN_FIXATION_FRAMES, fixation_counts,
                                         idt_labels)
from dyadbench.motion import GAZE7

GROUPS = ("all", "gaze", "head")
HEAD_PITCH_YAW = slice(0, 2)
LEFT_EYE, RIGHT_EYE = slice(3, 5), slice(5, 7)

# CompScore velocity bands (paper eq. 6), in the unit of ``velocity_unit``.
COMP_STABLE_BELOW = 20.0
COMP_SHIFT_BAND = (25.0, 90.0)
VELOCITY_UNITS = ("deg_per_frame", "deg_per_s")


@dataclass(frozen=True)
class MetricInfo:
    """What a user needs to read a number: direction and unit."""

    name: str
    higher_is_better: bool | None  # None: closer to the ground truth's own value is better
    units: str
    summary: str


METRICS: dict[str, MetricInfo] = {m.name: m for m in (
    MetricInfo("mae", False, "deg", "mean over frames x dims of |pred - gt|"),
    MetricInfo("vel", False, "(deg/frame)^2", "mean over frames x dims of the squared velocity error"),
    MetricInfo("vel_abs", False, "deg/frame", "mean over frames x dims of the absolute velocity error"),
    MetricInfo("mee", False, "(deg/frame)^2", "|E(pred) - E(gt)|, E = mean over frames of sum over dims of (dx)^2"),
    MetricInfo("mee_frame", False, "(deg/frame)^2", "mean over frames of |sum (dx_pred)^2 - sum (dx_gt)^2|"),
    MetricInfo("fix_ratio", None, "fraction", "I-DT fixation frames / labelled frames"),
    MetricInfo("comp_score", None, "deg/frame or cosine", "eye-head compensation score (paper eq. 6-7)"),
    MetricInfo("sim_gt", True, "-", "1 - (|Fix_gt - Fix| + |Comp_gt - Comp|) from split-level aggregates"),
    MetricInfo("sim_gt_seq", True, "-", "mean over sequences of the per-sequence SimWithGT"),
    MetricInfo("bas", True, "-", "beat alignment score, mean over motion beats of exp(-d^2 / 2 sigma^2)"),
    MetricInfo("bas_delta", True, "-", "BAS with the sequence's own speech minus BAS with shuffled speech"),
    MetricInfo("style_ce", False, "-", "1 - cos(style(gt window), style(pred window)), mean over windows"),
)}

GROUP_HEADERS = {"all": "All", "gaze": "Gaze", "head": "Head"}
#: BAS variants the suite reports per group (``dyadbench.scoring.gaze``): matched, shuffled speech, and
#: their difference, in both directions (m2a, a2m), for the prediction and (``gt_``) the ground truth.
BAS_VARIANTS = ("bas", "bas_shuffled", "bas_delta", "bas_a2m", "bas_a2m_shuffled", "bas_a2m_delta")


def _column(key: str, header: str, table: bool = True, reference: str | None = None) -> ColumnSpec:
    """A key's declaration: its metric's direction (:data:`METRICS`; None for ground-truth reference values
    ``gt_*``, shuffled-speech references and the saccade ratio, judged against the ground truth's), scale
    100 printed as % for the fixation/saccade ratios."""
    base = key
    for group in GROUPS:
        base = base.removesuffix(f"_{group}")
    base = base.replace("bas_a2m", "bas")
    descriptive = key.startswith("gt_") or "shuffled" in key or base == "saccade_ratio"
    direction = None if descriptive else METRICS[base].higher_is_better
    percent = base.removeprefix("gt_") in ("fix_ratio", "saccade_ratio")
    return ColumnSpec(key, header, direction, 100.0 if percent else 1.0, "%" if percent else None,
                      table and reference is None, reference)


def _columns() -> SuiteColumns:
    """StyGazeTalk Table 2 (per group: MAE, Vel, MEE, BAS; CE after All) and Table 3 (saccade %, fixation %,
    CompScore, SimScore) printed, the ground truth's Table 3 values as the tables' ground-truth row; then
    dyadbench's extras (Head dBAS, Sim_seq) and every other key the suite reports (kept in results and
    ``long.csv``). Ranked by SimScore (``sim_gt``, higher is
    better), the paper's summary of gaze behaviour."""
    table2 = []
    for group, title in GROUP_HEADERS.items():
        table2 += [(f"{m}_{group}", f"{title} {h}") for m, h in (("mae", "MAE"), ("vel", "Vel"), ("mee", "MEE"))]
        table2 += [("style_ce", "CE")] if group == "all" else []
        table2 += [(f"bas_{group}", f"{title} BAS")]
    printed = table2 + [
        ("saccade_ratio", "saccade"), ("fix_ratio", "fixation"), ("comp_score", "CompScore"), ("sim_gt", "SimScore")]
    extras = [("bas_delta_head", "Head dBAS"), ("sim_gt_seq", "Sim_seq")]
    references = [("gt_saccade_ratio", "GT saccade"), ("gt_fix_ratio", "GT fixation"),
                  ("gt_comp_score", "GT CompScore")]
    others = ([f"{m}_{g}" for m in ("vel_abs", "mee_frame") for g in GROUPS]
              + [f"{prefix}{v}_{g}" for prefix in ("", "gt_") for v in BAS_VARIANTS for g in GROUPS])
    seen = {key for key, _ in printed + extras + references}
    return SuiteColumns("gaze", tuple([_column(k, h) for k, h in printed]
                                      + [_column(k, h, table=False) for k, h in extras]
                                      + [_column(k, h, reference=k.removeprefix("gt_")) for k, h in references]
                                      + [_column(k, k, table=False) for k in others if k not in seen]),
                        primary="sim_gt")


#: The suite's columns (:mod:`dyadbench.metrics.columns`).
COLUMNS = _columns()


def check_motion(motion: np.ndarray, name: str) -> np.ndarray:
    """``motion`` as float64 (T, 7) finite degrees, or :class:`InputError` naming ``name``."""
    arr = np.asarray(motion, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != GAZE7.dim:
        raise InputError(name, f"gaze-head motion must be (T, 7) degrees {GAZE7.units}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise InputError(name, f"{int((~np.isfinite(arr)).any(axis=1).sum())} frames contain NaN or inf")
    return arr


def check_pair(pred: np.ndarray, gt: np.ndarray, name: str = "pred") -> tuple[np.ndarray, np.ndarray]:
    pred, gt = check_motion(pred, name), check_motion(gt, f"{name} (ground truth)")
    if pred.shape != gt.shape:
        raise InputError(name, f"prediction {pred.shape} and ground truth {gt.shape} differ in length")
    return pred, gt


def group_dims(motion: np.ndarray, group: str) -> np.ndarray:
    """The group's columns: all (7), gaze (4: L pitch/yaw, R pitch/yaw), head (3: pitch, yaw, roll)."""
    if group not in GROUPS:
        raise InputError(None, f"group must be one of {GROUPS}, got {group!r}")
    return GAZE7.component(motion, group)


def velocity(motion: np.ndarray) -> np.ndarray:
    """First difference per frame: v_t = x_t - x_{t-1} for t = 1..T-1, in degrees per frame, (T-1, D)."""
    return np.diff(np.asarray(motion, dtype=np.float64), axis=0)


def mae(pred: np.ndarray, gt: np.ndarray, group: str = "all") -> float:
    """MAE = (1 / (T D)) sum_t sum_d |x̂_{t,d} - x_{t,d}| over the group's D dims, in degrees.

    A mean over frames x dims (not a norm), so MAE_all = (4 MAE_gaze + 3 MAE_head) / 7.
    """
    pred, gt = check_pair(pred, gt)
    return float(np.mean(np.abs(group_dims(pred, group) - group_dims(gt, group))))


def vel(pred: np.ndarray, gt: np.ndarray, group: str = "all") -> float:
    """Vel = (1 / ((T-1) D)) sum_t sum_d (Δx̂_{t,d} - Δx_{t,d})², Δx_t = x_t - x_{t-1}, in (°/frame)².

    The squared reading is the only one consistent with the paper's Vel and MEE magnitudes together.
    """
    pred, gt = check_pair(pred, gt)
    return float(np.mean((velocity(group_dims(pred, group)) - velocity(group_dims(gt, group))) ** 2))


def vel_abs(pred: np.ndarray, gt: np.ndarray, group: str = "all") -> float:
    """Vel_abs = (1 / ((T-1) D)) sum_t sum_d |Δx̂_{t,d} - Δx_{t,d}|, in °/frame (named variant of Vel)."""
    pred, gt = check_pair(pred, gt)
    return float(np.mean(np.abs(velocity(group_dims(pred, group)) - velocity(group_dims(gt, group)))))


def motion_energy(motion: np.ndarray, group: str = "all") -> float:
    """E = (1 / (T-1)) sum_t sum_{d in group} (Δx_{t,d})², in (°/frame)²."""
    v = velocity(group_dims(check_motion(motion, "motion"), group))
    return float(np.mean(np.sum(v ** 2, axis=1)))


def mee(pred: np.ndarray, gt: np.ndarray, group: str = "all") -> float:
    """MEE = |E(pred) - E(gt)| for one sequence, E = :func:`motion_energy` (sum over the group's dims).

    The suite averages it over sequences. Because the absolute value is taken per sequence after summing
    dims, MEE_all <= MEE_gaze + MEE_head (as in every row of the paper's table).
    """
    pred, gt = check_pair(pred, gt)
    return abs(motion_energy(pred, group) - motion_energy(gt, group))


def mee_frame(pred: np.ndarray, gt: np.ndarray, group: str = "all") -> float:
    """MEE_frame = (1 / (T-1)) sum_t |sum_d (Δx̂_{t,d})² - sum_d (Δx_{t,d})²| (named variant of MEE)."""
    pred, gt = check_pair(pred, gt)
    ep = np.sum(velocity(group_dims(pred, group)) ** 2, axis=1)
    eg = np.sum(velocity(group_dims(gt, group)) ** 2, axis=1)
    return float(np.mean(np.abs(ep - eg)))


# --- gaze patterns -------------------------------------------------------------------------------------

def fixation_labels(motion: np.ndarray, *, threshold_deg: float = DISPERSION_THRESHOLD_DEG,
                    min_frames: int = MIN_FIXATION_FRAMES, eyes: str = "pooled",
                    include_breaking_sample: bool = False, name: str = "motion") -> np.ndarray:
    """Per-frame I-DT labels (T,) of a (T, 7) gaze–head sequence: 1 fixation, 0 saccade (eye angles only)."""
    motion = check_motion(motion, name)
    return idt_labels(group_dims(motion, "gaze"), threshold_deg=threshold_deg, min_frames=min_frames,
                      eyes=eyes, include_breaking_sample=include_breaking_sample, name=name)


def fix_ratio(sequences: list[np.ndarray], **idt_params) -> float:
    """FixRatio = N_fix / (N_fix + N_sac), frame counts pooled over all ``sequences`` (paper eq. 5).

    ``idt_params`` go to :func:`fixation_labels` (threshold_deg 3.5, min_frames 3, eyes "pooled",
    include_breaking_sample False). In [0, 1]; NaN when no frame is labelled.
    """
    n_fix = n_sac = 0
    for i, seq in enumerate(sequences):
        f, s = fixation_counts(fixation_labels(seq, name=f"sequence {i}", **idt_params))
        n_fix, n_sac = n_fix + f, n_sac + s
    return n_fix / (n_fix + n_sac) if n_fix + n_sac else float("nan")


def compensation_frames(motion: np.ndarray, *, velocity_unit: str = "deg_per_frame", fps: float = 25.0,
                        stable_below: float = COMP_STABLE_BELOW,
                        shift_band: tuple[float, float] = COMP_SHIFT_BAND, include_roll: bool = False,
                        name: str = "motion") -> np.ndarray:
    """Per-velocity-frame compensation score (T-1,), paper eq. 6, with 2-D (pitch, yaw) vectors.

    h_t = head (pitch, yaw) velocity; e_t = mean of the two eyes' (pitch, yaw) velocities; g_t = e_t + h_t:

    - score_t = -‖h_t‖            if ‖g_t‖ < ``stable_below`` (20)
    - score_t = -cos θ(h_t, e_t)  if 25 <= ‖g_t‖ <= 90 (``shift_band``); 0 if ‖h_t‖ or ‖e_t‖ is 0
    - score_t = 0                 otherwise (the 20–25 gap included)

    Velocities in °/frame (``velocity_unit="deg_per_frame"``) or °/s (× ``fps``). Head roll is excluded
    (``include_roll=True``: ‖h_t‖ of the first branch includes the roll velocity; g and θ stay 2-D).
    Eyes counter-rotating the head (VOR, cos θ = -1) score +1; eyes and head moving together score -1.
    """
    if velocity_unit not in VELOCITY_UNITS:
        raise InputError(name, f"velocity_unit must be one of {VELOCITY_UNITS}, got {velocity_unit!r}")
    v = velocity(check_motion(motion, name))
    if velocity_unit == "deg_per_s":
        v = v * fps
    h = v[:, HEAD_PITCH_YAW]
    e = 0.5 * (v[:, LEFT_EYE] + v[:, RIGHT_EYE])
    g = e + h
    h_norm, e_norm, g_norm = (np.linalg.norm(a, axis=1) for a in (h, e, g))
    stable_cost = np.linalg.norm(v[:, 0:3], axis=1) if include_roll else h_norm
    denom = h_norm * e_norm
    cos = np.divide(np.sum(h * e, axis=1), denom, out=np.zeros_like(denom), where=denom > 0)
    low, high = shift_band
    return np.where(g_norm < stable_below, -stable_cost,
                    np.where((g_norm >= low) & (g_norm <= high), -cos, 0.0))


def comp_score(sequences: list[np.ndarray], **comp_params) -> float:
    """CompScore = mean over all velocity frames of all ``sequences`` of :func:`compensation_frames` (eq. 7)."""
    frames = [compensation_frames(seq, name=f"sequence {i}", **comp_params) for i, seq in enumerate(sequences)]
    pooled = np.concatenate(frames) if frames else np.zeros(0)
    return float(pooled.mean()) if pooled.size else float("nan")


def sim_with_gt(fix_gt: float, comp_gt: float, fix_pred: float, comp_pred: float) -> float:
    """SimWithGT = 1 - (|Fix_GT - Fix_pred| + |Comp_GT - Comp_pred|), Fix as a fraction (paper eq. 8).

    At most 1 (equal aggregates); can be negative. Computed once from split-level aggregates it
    reproduces every published SimScore; it cannot tell real-but-mismatched motion from a faithful model,
    so the suite also reports the mean of per-sequence values (``sim_gt_seq``).
    """
    return 1.0 - (abs(fix_gt - fix_pred) + abs(comp_gt - comp_pred))


# --- style cosine error (hook for a frozen style encoder) ----------------------------------------------

class StyleEncoder(Protocol):
    """A frozen, versioned style encoder: motion windows (B, window, 7) in degrees -> embeddings (B, d).

    The encoder normalises its input itself. ``digest`` identifies the weights (recorded in results);
    ``window`` and ``hop`` are the window length and stride in frames.
    """

    digest: str
    window: int
    hop: int

    def __call__(self, windows: np.ndarray) -> np.ndarray: ...


def sliding_windows(motion: np.ndarray, window: int, hop: int) -> np.ndarray:
    """(n, window, D) windows starting at 0, hop, 2·hop, ... that fit entirely; n may be 0."""
    motion = np.asarray(motion)
    starts = np.arange(0, len(motion) - window + 1, hop) if window <= len(motion) else np.zeros(0, dtype=int)
    return np.stack([motion[s:s + window] for s in starts]) if len(starts) else np.zeros((0, window, motion.shape[1]))


def style_cosine_error(emb_gt: np.ndarray, emb_pred: np.ndarray) -> float:
    """E_style = mean over windows w of 1 - cos(s_gt_w, s_pred_w); NaN with no windows. In [0, 2]."""
    a, b = np.asarray(emb_gt, dtype=np.float64), np.asarray(emb_pred, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2:
        raise InputError("style embeddings", f"need two (n, d) arrays of one shape, got {a.shape} and {b.shape}")
    if not len(a):
        return float("nan")
    norms = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    if np.any(norms == 0):
        raise InputError("style embeddings", "a style embedding has zero norm; cosine is undefined")
    return float(np.mean(1.0 - np.sum(a * b, axis=1) / norms))
