"""Stage-2 training: the listening-head predictor on windows tokenised on the fly by the frozen tokenizer.

Each step samples [t−P, t+F) windows (neutral-past and pre-start augmentation, D24), tokenises the
listener's 48-frame window (D12), and minimises the weighted CE + keyframe-timing loss of the F future
classes given the P past classes and the speaker window. AdamW with linear warm-up then cosine. The
weights with the lowest validation weighted CE are kept; the history also records the CE of the
train-set class-frequency (unigram) predictor on the same validation windows.
"""

from __future__ import annotations

import copy
import time

import numpy as np
import torch
from tqdm import tqdm

from dyadbench.training.ema import EMA
from models.sfms.bundle import SFMS
from models.sfms.config import PredictorConfig
from models.sfms.data import DirectedClip, PredictorBatch, sample_predictor_batch
from models.sfms.distributed import World, wrap
from models.sfms.predictor import SFMSPredictor, class_weights, predictor_losses
from models.sfms.schedule import warmup_cosine
from models.sfms.tokenizer import SFMSTokenizer


def _tensors(batch: PredictorBatch, device: torch.device) -> tuple[torch.Tensor, ...]:
    return tuple(torch.as_tensor(x, device=device) for x in (batch.listener, batch.speaker, batch.audio, batch.valid))


@torch.no_grad()
def tokenise_targets(tokenizer: SFMSTokenizer, listener: torch.Tensor, past: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(past classes (B, P), future classes (B, F)) of the listener windows ((B, P, d), (B, F, d) per channel)."""
    classes = tokenizer.encode(listener)[0]
    return classes[:, :past], classes[:, past:]


def unigram_ce(train_targets: torch.Tensor, val_targets: torch.Tensor, weights: torch.Tensor) -> float:
    """Weighted CE of predicting every frame with the train class frequencies (add-one smoothed)."""
    n = weights.shape[0]
    freq = torch.bincount(train_targets.flatten(), minlength=n).float() + 1.0
    logp = (freq / freq.sum()).log()
    return float((weights[val_targets] * -logp[val_targets]).sum() / val_targets.numel())


@torch.no_grad()
def validation_ce(model: SFMSPredictor, tokenizer: SFMSTokenizer, batch: PredictorBatch,
                  weights: torch.Tensor) -> tuple[float, torch.Tensor]:
    was_training = model.training
    model.eval()
    lis, spk, aud, valid = _tensors(batch, weights.device)
    past, target = tokenise_targets(tokenizer, lis, model.cfg.past)
    logits = model(past, spk, aud, valid)
    ce = predictor_losses(logits, target, weights, model.cfg)["ce"]
    model.train(was_training)
    return float(ce), target


def fit_predictor(cfg: PredictorConfig, tokenizer: SFMSTokenizer, train: list[DirectedClip],
                  val: list[DirectedClip], *, audio_mean: np.ndarray, audio_std: np.ndarray, seed: int,
                  world: World | None = None, val_windows: int = 512, val_every: int = 100,
                  progress: bool = True) -> tuple[SFMS, dict]:
    """Train the predictor on normalised directed clips; returns (best SFMS in eval mode, history)."""
    world = world or World(0, 1, torch.device("cpu"))
    if tokenizer.cfg.window != cfg.window:
        raise ValueError(f"predictor past + future ({cfg.window}) must equal the tokenizer window "
                         f"({tokenizer.cfg.window})")
    torch.manual_seed(seed)
    tokenizer = tokenizer.to(world.device).eval()
    for p in tokenizer.parameters():
        p.requires_grad_(False)
    model = SFMSPredictor(cfg, tokenizer.cfg.dim, tokenizer.cfg.n_classes, tokenizer.cfg.per_channel)
    model.audio_mean.copy_(torch.as_tensor(audio_mean))
    model.audio_std.copy_(torch.as_tensor(audio_std))
    model.to(world.device).train()
    net = wrap(model, world)
    weights = class_weights(tokenizer.cfg.n_classes, tokenizer.cfg.effective_keyframes, tokenizer.cfg.window
                            ).to(world.device)
    rng = np.random.default_rng([seed, world.rank])
    val_batch = sample_predictor_batch(val, cfg, val_windows, np.random.default_rng([seed, 999]))
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, betas=cfg.betas, weight_decay=cfg.weight_decay)
    warm = int(round(cfg.warmup_frac * cfg.steps))
    history: dict = {"steps": [], "val": [], "seed": seed, "world_size": world.size}
    seen_targets = []
    best_val, best_state, best_step = float("inf"), None, -1
    ema = EMA(model, cfg.ema_decay) if cfg.ema_decay > 0 else None
    t0 = time.perf_counter()
    bar = tqdm(range(cfg.steps), desc="sfms predictor", disable=not (progress and world.main))
    for step in bar:
        for group in opt.param_groups:
            group["lr"] = warmup_cosine(step, cfg.steps, warm, cfg.lr, cfg.lr_min)
        lis, spk, aud, valid = _tensors(sample_predictor_batch(train, cfg, cfg.batch, rng), world.device)
        past, target = tokenise_targets(tokenizer, lis, cfg.past)
        seen_targets.append(target.cpu())
        losses = predictor_losses(net(past, spk, aud, valid), target, weights, cfg)
        opt.zero_grad(set_to_none=True)
        losses["loss"].backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
        opt.step()
        if ema is not None:
            ema.update(model)
        record = {k: float(v.detach()) for k, v in losses.items()}
        record["step"] = step
        history["steps"].append(record)
        bar.set_postfix(loss=f"{record['loss']:.3f}")
        if world.main and ((step + 1) % val_every == 0 or step + 1 == cfg.steps):
            scored = ema.shadow if ema is not None else model
            ce, val_targets = validation_ce(scored, tokenizer, val_batch, weights)
            history["val"].append({"step": step + 1, "ce": ce,
                                   "unigram_ce": unigram_ce(torch.cat(seen_targets), val_targets.cpu(),
                                                            weights.cpu())})
            if ce < best_val:
                best_val, best_step, best_state = ce, step + 1, copy.deepcopy(scored.state_dict())
    if best_state is not None:
        model.load_state_dict(best_state)
    history.update(best_val_ce=best_val, best_step=best_step, train_seconds=time.perf_counter() - t0)
    return SFMS(tokenizer.cpu(), model.cpu()).eval(), history
