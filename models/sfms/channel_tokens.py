"""Per-channel keyframe allocation of SFMS (``mask_sharing = "channel"``): the paper's "channel-wise
tokenization with independent keyframe allocation" (§V-B; "channel-level … keyframe log-probability",
§IV-B2; per-channel keyframe probabilities in Fig. 8).

The paper states the allocation but not its mechanics; the decisions taken here (D1 of the spec, the
alternative it names "d masks, scalar codes per channel"):

- **Scores.** Φ_score is unchanged except its last layer, Linear(W → d) instead of Linear(W → 1): one
  log-probability s_{t,c} per frame and channel, still computed from all channels ("context-aware").
- **Budget.** Each channel c independently gets exactly k keyframes: Algorithm 1 (Gumbel soft top-k
  with straight-through, same τ, ε, suppression radius) runs on every column s_{·,c} as on the shared
  score vector, and at inference the deterministic top-k per column. The keyframe budget is therefore
  the same number of keyframe *values* as the shared mask (k frames × d channels = k·d values per
  window); what changes is that each channel places its own k.
- **Tokens.** One token per (keyframe frame t, channel c): its embedding is
  Linear(1 → W)(m_{t,c}) + E_chan[c], concatenated with PE(t) as in the shared model; the keyframe
  encoder attends over all keyframe tokens of the window (all channels, so codes keep inter-channel
  context) plus the sink slot, and each token is quantised on its own (FSQ/VQ, same codebook size).
  Class of (t, c): 0 = transition, 1 + code = keyframe, so classes are (B, T, d) instead of (B, T).
  At equal k a per-channel window carries d times as many codes as a shared one (k·d against k).
- **Inpainter.** The memory is the keyframe tokens: Linear([r·z_q ; PE(t)]) + E_mem[c] (r the
  straight-through mask value of the token). The T frame queries (blank ⊕ PE) go through the
  transition encoder and decoder as before; the decoder's per-frame keyframe flag is replaced by the
  fraction of channels keyed at that frame (its mean of r), since no single per-frame z_q exists.
- **Predictor.** The listener's past classes (B, P, d) are embedded per channel (one table of d·V
  rows, the mean over channels gives the frame vector); the output layer gives d·V logits per future
  frame, i.e. (B, F, d, V). The loss is the same weighted CE over all (frame, channel) tokens, and the
  keyframe-timing term runs on each channel's 8-frame keyframe probability sequence.

This module holds the gather/scatter between the (B, T, d) grid and the padded token list.
"""

from __future__ import annotations

import torch


def to_rows(x: torch.Tensor) -> torch.Tensor:
    """(B, T, d) → (B·d, T): each channel's column becomes a row (for the per-row top-k functions)."""
    b, t, d = x.shape
    return x.transpose(1, 2).reshape(b * d, t)


def from_rows(x: torch.Tensor, dim: int) -> torch.Tensor:
    """Inverse of :func:`to_rows`: (B·d, T) → (B, T, d)."""
    return x.reshape(-1, dim, x.shape[-1]).transpose(1, 2)


def gather_tokens(mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The keyframe tokens of a 0/1 mask (B, T, d), as (flat index (B, L), frame (B, L), channel (B, L),
    pad (B, L) True = no token), L = the largest token count of the batch (at least 1). Tokens of a row
    come in ascending flat order t·d + c."""
    b, t, d = mask.shape
    flat = mask.reshape(b, t * d) > 0.5
    counts = flat.sum(1)
    length = max(int(counts.max()) if b else 0, 1)
    order = torch.argsort((~flat).to(torch.int8), dim=1, stable=True)[:, :length]
    pad = torch.arange(length, device=mask.device)[None, :] >= counts[:, None]
    return order, torch.div(order, d, rounding_mode="floor"), order % d, pad


def scatter_tokens(values: torch.Tensor, flat: torch.Tensor, pad: torch.Tensor, shape: tuple[int, int, int],
                   fill: int | float = 0) -> torch.Tensor:
    """Token values (B, L) back on the (B, T, d) grid; positions without a token hold ``fill``."""
    b, t, d = shape
    out = values.new_full((b, t * d), fill)
    out.scatter_(1, flat, torch.where(pad, out.gather(1, flat), values))
    return out.view(b, t, d)
