"""Stage-1 training: the sparse keyframe tokenizer with two optimisers (spec §2.10, D4–D7).

Phase A (warm-up, ``warmup_frac`` of the steps, dynamic keyframes only): the scorer is frozen and
masks are random k-subsets (Algorithm 1 on zero logits); the main optimiser warms up linearly.
Phase B: one backward pass of the total loss, both optimisers step (the scorer every
``scorer_update_every`` steps), each with its own cosine schedule; τ anneals exponentially.
The weights with the lowest validation reconstruction MSE (eval mode, deterministic top-k) are kept.
"""

from __future__ import annotations

import copy
import time

import numpy as np
import torch
from tqdm import tqdm

from dyadbench.training.ema import EMA
from models.sfms.config import TokenizerConfig
from models.sfms.data import sample_motion_windows
from models.sfms.distributed import World, wrap
from models.sfms.schedule import cosine, temperature, warmup_cosine
from models.sfms.tokenizer import SFMSTokenizer


def eval_windows(arrays: list[np.ndarray], window: int, limit: int = 512) -> np.ndarray:
    """Non-overlapping windows of every array, at most ``limit`` (deterministic validation/test set)."""
    out = [a[o: o + window] for a in arrays for o in range(0, a.shape[0] - window + 1, window)]
    if not out:
        raise ValueError(f"no sequence is at least {window} frames long")
    return np.stack(out[:limit]).astype(np.float32)


@torch.no_grad()
def reconstruction_mse(model: SFMSTokenizer, windows: np.ndarray, batch: int = 256) -> dict[str, float]:
    """Eval-mode MSE of ``reconstruct`` on normalised windows: z-space and raw (denormalised) units; the
    windows go to the model's device."""
    was_training = model.training
    model.eval()
    z_sum = raw_sum = 0.0
    for i in range(0, len(windows), batch):
        m = torch.as_tensor(windows[i: i + batch], device=model.motion_std.device)
        rec = model.reconstruct(m)
        z_sum += float((rec - m).pow(2).mean(dim=(1, 2)).sum())
        raw_sum += float((model.denormalise(rec) - model.denormalise(m)).pow(2).mean(dim=(1, 2)).sum())
    model.train(was_training)
    return {"mse_z": z_sum / len(windows), "mse_raw": raw_sum / len(windows)}


def code_perplexity(codes: torch.Tensor, n_codes: int) -> float:
    """exp(entropy) of the used code indices (1 = one code, n_codes = uniform use)."""
    if codes.numel() == 0:
        return 0.0
    p = torch.bincount(codes.flatten(), minlength=n_codes).float() / codes.numel()
    return float(torch.exp(-(p[p > 0] * p[p > 0].log()).sum()))


def _clip(params: list[torch.nn.Parameter], norm: float) -> None:
    grads = [p for p in params if p.grad is not None]
    if grads:
        torch.nn.utils.clip_grad_norm_(grads, norm)


def fit_tokenizer(cfg: TokenizerConfig, train: list[np.ndarray], val: np.ndarray, *, motion_mean: np.ndarray,
                  motion_std: np.ndarray, seed: int, world: World | None = None,
                  progress: bool = True, model_factory=SFMSTokenizer) -> tuple[SFMSTokenizer, dict]:
    """Train on normalised ``train`` sequences on ``world``'s device; returns (best model on the CPU in eval
    mode, history).
    ``model_factory(cfg)`` builds the model (another tokenizer with the same training interface, e.g.
    :class:`models.sfms.dense_vq.DenseVQVAE`; one without scorer parameters gets no second optimiser)."""
    world = world or World(0, 1, torch.device("cpu"))
    torch.manual_seed(seed)
    model = model_factory(cfg)
    model.motion_mean.copy_(torch.as_tensor(motion_mean))
    model.motion_std.copy_(torch.as_tensor(motion_std))
    model.to(world.device).train()
    net = wrap(model, world)
    rng = np.random.default_rng([seed, world.rank])
    gen = torch.Generator(device=world.device).manual_seed(seed * 1000 + world.rank)
    main_params, score_params = model.main_parameters(), model.scorer_parameters()
    opt_main = torch.optim.AdamW(main_params, lr=cfg.lr_main, betas=cfg.betas, weight_decay=cfg.weight_decay)
    opt_score = (torch.optim.AdamW(score_params, lr=cfg.lr_scorer, betas=cfg.betas, weight_decay=cfg.weight_decay)
                 if score_params else torch.optim.SGD([torch.zeros(0, requires_grad=True)], lr=0.0))  # no-op
    dynamic = cfg.keyframe_mode == "dynamic"
    warm = int(round(cfg.warmup_frac * cfg.steps)) if dynamic else 0
    phase_b = cfg.steps - warm
    history: dict = {"steps": [], "val": [], "seed": seed, "world_size": world.size}
    best_val, best_state, best_step = float("inf"), None, -1
    ema = EMA(model, cfg.ema_decay) if cfg.ema_decay > 0 else None
    t0 = time.perf_counter()
    bar = tqdm(range(cfg.steps), desc=f"sfms tokenizer ({cfg.keyframe_mode})", disable=not (progress and world.main))
    for step in bar:
        warming = step < warm
        j = step - warm
        if warming:
            lr_main = cfg.lr_main * (step + 1) / warm
        else:
            lr_main = cosine(j, phase_b, cfg.lr_main, cfg.lr_min) if warm else warmup_cosine(
                step, cfg.steps, 0, cfg.lr_main, cfg.lr_min)
            model.tau.fill_(temperature(j, phase_b, cfg.tau_start, cfg.tau_min, cfg.tau_anneal_frac))
        for group in opt_main.param_groups:
            group["lr"] = lr_main
        for group in opt_score.param_groups:
            group["lr"] = cosine(max(j, 0), phase_b, cfg.lr_scorer, cfg.lr_min)
        m = torch.as_tensor(sample_motion_windows(train, cfg.batch, cfg.window, rng), device=world.device)
        dense_aux = cfg.dense_aux_weight * (1.0 - step / warm) if warming else 0.0
        losses = net(m, warmup=warming, dense_aux=dense_aux, generator=gen)
        opt_main.zero_grad(set_to_none=True)
        opt_score.zero_grad(set_to_none=True)
        losses["loss"].backward()
        _clip(main_params, cfg.grad_clip)
        _clip(score_params, cfg.grad_clip)
        opt_main.step()
        if dynamic and not warming and j % cfg.scorer_update_every == 0:
            opt_score.step()
        if ema is not None:
            ema.update(model)
        record = {k: float(v.detach()) for k, v in losses.items() if k != "codes"}
        record.update(step=step, tau=float(model.tau), lr_main=lr_main,
                      perplexity=code_perplexity(losses["codes"], cfg.n_codes))
        history["steps"].append(record)
        bar.set_postfix(loss=f"{record['loss']:.3f}", mse=f"{record['motion']:.3f}")
        if world.main and ((step + 1) % cfg.val_every == 0 or step + 1 == cfg.steps) and step + 1 > warm:
            scored = ema.shadow if ema is not None else model
            val_mse = reconstruction_mse(scored, val)
            history["val"].append({"step": step + 1, **val_mse})
            if val_mse["mse_z"] < best_val:
                best_val, best_step = val_mse["mse_z"], step + 1
                best_state = copy.deepcopy(scored.state_dict())
    if best_state is not None:
        model.load_state_dict(best_state)
    history.update(best_val_mse_z=best_val, best_step=best_step, train_seconds=time.perf_counter() - t0)
    return model.cpu().eval(), history
