"""Stage 2: teacher-forced generator training (spec §2.7, §2.9) with the style encoder frozen (D26).

One step (own notation of the spec): a window of M+1 ground-truth frames x_{u−1..u+M−1}; inputs
x_{u−1..u+M−2}, targets x_{u..u+M−1}; s = SE(inputs) (D7, the literal reading: the style window covers
M−1 targets), SE(the M frames before the inputs, "preceding") or SE(the M frames just before the first scored
target, "past": never a target, and with ``loss_outputs="last-n"`` exactly the inference window, see
:func:`style_window`);
loss λ·MSE + (1−λ)·velocity-MSE with x_{u−1} as the predecessor of the first output (D20).
Adam with cosine decay, gradient clipping; the weights with the lowest validation L_gen are kept (D27), or
those with the lowest validation L_mse ("val-mse": one criterion for every λ), or the final ones.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional as F
from tqdm import tqdm

from dyadbench.seeding import derive_seed
from models.stygazetalk.audio import raw_features
from models.stygazetalk.config import GeneratorConfig
from models.stygazetalk.data import Segment, WindowBank, build_window_bank, stacked_motion
from models.stygazetalk.normalise import ZScore
from models.stygazetalk.system import StyGazeTalkSystem
from models.stygazetalk.train_log import TrainLog


def generator_loss(pred: torch.Tensor, target: torch.Tensor, predecessor: torch.Tensor, lam: float
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(L_gen, L_mse, L_vel) with mean reductions (D20).

    .. math:: L = \\lambda \\, \\overline{(\\hat x - x)^2} + (1 - \\lambda)\\, \\overline{(\\Delta \\hat x - \\Delta x)^2}

    ``predecessor`` (B, 1, 7) is the ground-truth frame before the first output; it starts both
    difference sequences.
    """
    mse = F.mse_loss(pred, target)
    vel = F.mse_loss(torch.diff(torch.cat([predecessor, pred], 1), dim=1),
                     torch.diff(torch.cat([predecessor, target], 1), dim=1))
    return lam * mse + (1.0 - lam) * vel, mse, vel


@dataclass
class GeneratorTrainLog(TrainLog):
    step0_val_loss: float = float("nan")
    train_windows: int = 0


def first_scored(cfg: GeneratorConfig) -> int:
    """Index of the first output step the loss covers: 0 (all M outputs) or W (the last N, D8)."""
    return 0 if cfg.loss_outputs == "all" else cfg.warmup


def style_history(cfg: GeneratorConfig) -> int:
    """Frames a bank row must hold before x_{u−1} for the style window (the bank's ``pre``).

    "motion-window": 0; "preceding": M (x_{u−1−M..u−2}); "past": the window x_{u+f−M..u+f−1} before the
    first scored target x_{u+f} (f = :func:`first_scored`) starts u+f−M, i.e. max(0, M − f − 1) frames
    before x_{u−1}.
    """
    if cfg.style_input == "preceding":
        return cfg.window
    if cfg.style_input == "past":
        return max(0, cfg.window - first_scored(cfg) - 1)
    return 0


def style_window(cfg: GeneratorConfig, motion: torch.Tensor) -> torch.Tensor:
    """The M normalised frames the style encoder reads in training, from bank rows (B, pre+M+1, 7).

    A row holds x_{u−1−pre}..x_{u+M−1}; the targets are x_{u..u+M−1} (the loss scores x_{u+f..u+M−1}).

    - "motion-window" (D7, literal): the motion inputs x_{u−1..u+M−2}, M−1 of which are targets.
    - "preceding": x_{u−1−M..u−2}, the M frames before the inputs.
    - "past" (leak-free, as at inference): x_{u+f−M..u+f−1}, the M frames just before the first scored
      target. At inference s = SE(x_{t−M..t−1}) for new frames t.. = u+W..; with ``loss_outputs="last-n"``
      (f = W) the training window is exactly that one; with "all" (f = 0) it ends at x_{u−1}.
    """
    m, pre = cfg.window, motion.shape[1] - cfg.window - 1
    if pre < style_history(cfg):
        raise ValueError(f"{cfg.name}: style_input={cfg.style_input!r} needs {style_history(cfg)} frames before "
                         f"x_(u-1) in each bank row, got {pre}")
    if cfg.style_input == "motion-window":
        return motion[:, pre:-1]
    if cfg.style_input == "preceding":
        return motion[:, :m]
    end = pre + first_scored(cfg)  # row index of x_{u+f−1}, exclusive end = end + 1
    return motion[:, end + 1 - m:end + 1]


def window_loss(system: StyGazeTalkSystem, motion: torch.Tensor, audio: torch.Tensor,
                rollout: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Loss of a batch of bank windows: motion (B, pre+M+1, 7), audio (B, M, F), both normalised."""
    cfg = system.cfg
    pre = motion.shape[1] - cfg.window - 1
    window = motion[:, pre:]  # x_{u-1} .. x_{u+M-1}
    x_in, target = window[:, :-1], window[:, 1:]
    style = system.style(style_window(cfg, motion))
    pred = system.generator(audio, x_in, style, free_from=cfg.warmup + 1 if rollout else None)
    first = first_scored(cfg)  # D8
    return generator_loss(pred[:, first:], target[:, first:], x_in[:, first:first + 1], cfg.lam)


def banks_for(system: StyGazeTalkSystem, train: list[Segment], val: list[Segment],
              history: int | None = None) -> tuple[WindowBank, WindowBank]:
    """Train (grid stride) and val (stride N) window banks. ``history`` holds more frames before x_{u−1}
    than the style window needs (fewer, later window starts), so that arms with different style windows
    can train on the same windows; None = what the style window needs."""
    cfg = system.cfg
    pre = style_history(cfg) if history is None else max(history, style_history(cfg))
    kwargs = dict(window=cfg.window, pre=pre, motion_norm=system.motion_norm.np,
                  audio_features=system.audio_window)
    return (build_window_bank(train, stride=cfg.feature_grid_stride, desc="train windows", **kwargs),
            build_window_bank(val, stride=cfg.horizon, desc="val windows", **kwargs))


def fit_audio_norm(system: StyGazeTalkSystem, train: list[Segment]) -> None:
    """Audio z-score statistics from the whole train segments' features (D13)."""
    rows = np.concatenate([raw_features(system.cfg, s.audio) for s in train])
    system.audio_norm.load_state_dict(ZScore.fit(rows).state_dict())


@torch.no_grad()
def residual_pool(system: StyGazeTalkSystem, bank: WindowBank, batch: int, size: int) -> torch.Tensor:
    """``size`` teacher-forced residual vectors (target − output) drawn without replacement from ``bank``
    (seeded by the config seed), the pool of sampled decoding (X1), on the system's device."""
    system.eval()
    device = _device(system)
    residuals = []
    for lo in range(0, len(bank), batch):
        rows = _rows(bank.motion[lo:lo + batch], device)
        window = rows[:, -(system.cfg.window + 1):]
        x_in, target = window[:, :-1], window[:, 1:]
        style = system.style(style_window(system.cfg, rows))
        pred = system.generator(_rows(bank.audio[lo:lo + batch], device), x_in, style)
        residuals.append((target - pred).reshape(-1, target.shape[-1]))
    r = torch.cat(residuals)
    pick = np.random.default_rng(derive_seed("stygazetalk-residuals", system.cfg.seed)).choice(
        len(r), size=size, replace=len(r) < size)
    return r[torch.from_numpy(pick).to(r.device)]


def _device(system: StyGazeTalkSystem) -> torch.device:
    """The device the system's weights are on."""
    return system.residual_pool.device


def _rows(array: np.ndarray, device: torch.device | str) -> torch.Tensor:
    """Bank rows as a tensor on ``device``."""
    return torch.from_numpy(array).to(device)


def _val_loss(system: StyGazeTalkSystem, bank: WindowBank, batch: int) -> float:
    """Teacher-forced validation value of the selection criterion: L_gen, or L_mse alone for "val-mse"."""
    term = 1 if system.cfg.checkpoint_selection == "val-mse" else 0
    system.eval()
    device = _device(system)
    total, n = 0.0, 0
    with torch.no_grad():
        for lo in range(0, len(bank), batch):
            motion = _rows(bank.motion[lo:lo + batch], device)
            loss = window_loss(system, motion, _rows(bank.audio[lo:lo + batch], device))[term]
            total += loss.item() * motion.shape[0]
            n += motion.shape[0]
    return total / n


def train_generator(system: StyGazeTalkSystem, train: list[Segment], val: list[Segment], *,
                    progress: bool = True, history: int | None = None, device: str = "cpu") -> GeneratorTrainLog:
    """Train ``system.generator`` in place (normalisers and style encoder must already be set) on ``device``;
    the system is back on the CPU when it returns. Batches are drawn on the CPU, seeded alike on every device.

    ``history``: see :func:`banks_for` (None: the windows the style input needs)."""
    cfg = system.cfg
    torch.manual_seed(derive_seed("stygazetalk-generator", cfg.seed))
    if system.style_encoder is None:  # Base: no stage-1 checkpoint carries the statistics
        system.motion_norm.load_state_dict(ZScore.fit(stacked_motion(train)).state_dict())
    fit_audio_norm(system, train)
    train_bank, val_bank = banks_for(system, train, val, history)
    rng = np.random.default_rng(derive_seed("stygazetalk-generator-batches", cfg.seed))
    system.to(device)
    params = [p for p in system.generator.parameters() if p.requires_grad]
    opt = torch.optim.Adam(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda k: _cosine(k, cfg))
    log = GeneratorTrainLog(train_windows=len(train_bank))
    log.step0_val_loss = _val_loss(system, val_bank, cfg.batch)
    start = time.perf_counter()
    for step in tqdm(range(1, cfg.steps + 1), desc=f"generator {cfg.name}", disable=not progress or None):
        system.train()
        idx = rng.integers(0, len(train_bank), size=cfg.batch)
        rollout = cfg.rollout_prob > 0 and rng.random() < cfg.rollout_prob
        loss = window_loss(system, _rows(train_bank.motion[idx], device), _rows(train_bank.audio[idx], device),
                           rollout=rollout)[0]
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(params, cfg.grad_clip)
        opt.step()
        sched.step()
        if step % cfg.val_every == 0 or step == cfg.steps:
            log.record(step, loss.item(), _val_loss(system, val_bank, cfg.batch), system)
    if cfg.checkpoint_selection != "last":
        log.restore_best(system)
    system.residual_pool.copy_(residual_pool(system, val_bank, cfg.batch, system.residual_pool.shape[0]))
    system.cpu().eval()
    log.seconds = time.perf_counter() - start
    return log


def _cosine(step: int, cfg: GeneratorConfig) -> float:
    """LR multiplier: cosine decay from lr to lr_min over the run (D27)."""
    if cfg.lr_schedule != "cosine":
        return 1.0
    frac = min(step / max(cfg.steps, 1), 1.0)
    floor = cfg.lr_min / cfg.lr
    return floor + (1.0 - floor) * 0.5 * (1.0 + math.cos(math.pi * frac))
