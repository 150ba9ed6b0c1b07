"""The TIMAR network: interleaved turn tokens, a turn-level causal transformer and the diffusion head.

Tokens of one turn (F = frames per turn; 4F + 10 tokens)::

    <TURN> <USER_SPEECH> us×F </USER_SPEECH> <USER_MOTION> um×F </USER_MOTION>
           <AGENT_SPEECH> as×F </AGENT_SPEECH> <AGENT_MOTION> am×F </AGENT_MOTION> </TURN>

Speech tokens: frontend features (normalised by statistics stored with the weights) → trainable
Linear(speech_dim → d_t). Motion tokens: Linear(56 → d_t/2)–ReLU–Linear(d_t/2 → d_t)–ReLU, shared by
user motion and agent motion. All content tokens → Linear(d_t → D); then masked agent-motion tokens
become the learned [MASK], dropped user tokens (guidance training, or the unconditional branch) the
learned null token, and the 10 learned special tokens are interleaved. Positions are added, then
LayerNorm, the blocks, a final LayerNorm, and a second learned position embedding; the features at
agent-motion positions condition the diffusion head.

Motion statistics: ``motion_mean``/``motion_std`` buffers (identity unless the config's
``motion_norm`` is ``"per_dim"`` and training set them) standardise user and agent motion before the
motion embedding and the agent motion as the diffusion target; :meth:`TimarModel.sample_frames` maps
samples back to the original units. A checkpoint written before the buffers existed loads with
identity statistics (:func:`with_motion_statistics`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

from models.timar.backbone import KV, Block, concat_past
from models.timar.config import NUM_SPECIAL_TOKENS, TimarConfig
from models.timar.diffusion import GaussianDiffusion
from models.timar.head import DiffusionHead
from models.timar.layouts import timar_layout


def with_motion_statistics(state: dict, motion_dim: int) -> dict:
    """A state dict with identity motion statistics added where it has none (older checkpoints)."""
    identity = {"motion_mean": torch.zeros(motion_dim), "motion_std": torch.ones(motion_dim)}
    return {**{k: v for k, v in identity.items() if k not in state}, **state}


def agent_motion_slice(frames_per_turn: int) -> slice:
    """Token positions of the agent-motion frames inside a turn."""
    return slice(8 + 3 * frames_per_turn, 8 + 4 * frames_per_turn)


class TimarModel(nn.Module):
    def __init__(self, cfg: TimarConfig):
        super().__init__()
        self.cfg = cfg
        d_t, dim, length = cfg.token_dim, cfg.dim, cfg.tokens_per_turn
        self.register_buffer("speech_mean", torch.zeros(cfg.speech_dim))
        self.register_buffer("speech_std", torch.ones(cfg.speech_dim))
        self.register_buffer("motion_mean", torch.zeros(cfg.motion_dim))
        self.register_buffer("motion_std", torch.ones(cfg.motion_dim))
        self.speech_proj = nn.Linear(cfg.speech_dim, d_t)
        self.motion_embed = nn.Sequential(nn.Linear(cfg.motion_dim, d_t // 2), nn.ReLU(),
                                          nn.Linear(d_t // 2, d_t), nn.ReLU())
        self.token_proj = nn.Linear(d_t, dim)
        self.special_tokens = nn.Parameter(torch.zeros(NUM_SPECIAL_TOKENS, dim))
        self.mask_token = nn.Parameter(torch.zeros(dim))
        self.null_token = nn.Parameter(torch.zeros(dim))
        positions = length * cfg.max_turns if cfg.variant == "faithful" else length
        self.pos_embed = nn.Parameter(torch.zeros(positions, dim))
        self.head_pos_embed = nn.Parameter(torch.zeros(positions, dim))
        if cfg.variant == "stream":  # relative encoding: a learned key offset per layer and turn distance
            self.turn_keys = nn.Parameter(torch.zeros(cfg.depth, cfg.max_turns, dim))
        self.input_norm = nn.LayerNorm(dim, eps=1e-6)
        self.blocks = nn.ModuleList(Block(dim, cfg.heads, cfg.mlp_ratio, cfg.dropout, cfg.attn_dropout) for _ in range(cfg.depth))
        self.norm = nn.LayerNorm(dim, eps=1e-6)
        self._init_weights()
        self.head = DiffusionHead(cfg.motion_dim, dim, cfg.head_width, cfg.head_blocks)
        self.train_diffusion = GaussianDiffusion.training(cfg.train_steps)
        self.sample_diffusion = GaussianDiffusion.respaced(cfg.train_steps, cfg.sampling_steps)
        self.agent_slice = agent_motion_slice(cfg.frames_per_turn)
        self.loss_groups = timar_layout(cfg.motion_dim).loss_groups

    def _init_weights(self) -> None:
        for p in (self.special_tokens, self.mask_token, self.null_token, self.pos_embed, self.head_pos_embed):
            nn.init.normal_(p, std=0.02)
        if self.cfg.variant == "stream":
            nn.init.normal_(self.turn_keys, std=0.02)
        for module in self.modules():
            if isinstance(module, nn.Linear):
                nn.init.xavier_uniform_(module.weight)
                nn.init.zeros_(module.bias)

    # --- motion units --------------------------------------------------------------------------------
    def normalize_motion(self, motion: torch.Tensor) -> torch.Tensor:
        """Original units -> the model's units (identity with the default statistics)."""
        return (motion - self.motion_mean) / self.motion_std

    def denormalize_motion(self, motion: torch.Tensor) -> torch.Tensor:
        """The model's units -> original units (inverse of :meth:`normalize_motion`)."""
        return motion * self.motion_std + self.motion_mean

    # --- tokens --------------------------------------------------------------------------------------
    def turn_tokens(self, user_speech: torch.Tensor, user_motion: torch.Tensor, agent_speech: torch.Tensor,
                    agent_motion: torch.Tensor | None = None, agent_masked: torch.Tensor | None = None,
                    user_null: torch.Tensor | None = None) -> torch.Tensor:
        """Interleaved tokens (B, N, 4F+10, D) of N turns.

        Inputs are (B, N, F, ·): speech features, motion (56-d, original units). ``agent_motion`` None means every
        agent slot is [MASK]; else ``agent_masked`` (B, N, F) bool picks the [MASK] slots.
        ``user_null`` (B, N, 2F) bool replaces user speech (first F) / motion (last F) tokens by null.
        """
        def speech(x: torch.Tensor) -> torch.Tensor:
            return self.token_proj(self.speech_proj((x - self.speech_mean) / self.speech_std))

        def motion(x: torch.Tensor) -> torch.Tensor:
            return self.token_proj(self.motion_embed(self.normalize_motion(x)))

        us, um, ags = speech(user_speech), motion(user_motion), speech(agent_speech)
        if agent_motion is None:
            am = self.mask_token.expand_as(ags)
        else:
            am = motion(agent_motion)
            am = torch.where(agent_masked[..., None], self.mask_token, am)
        if user_null is not None:
            frames = us.shape[2]
            us = torch.where(user_null[..., :frames, None], self.null_token, us)
            um = torch.where(user_null[..., frames:, None], self.null_token, um)
        sp = self.special_tokens.expand(*us.shape[:2], -1, -1)
        parts = [sp[:, :, 0:2], us, sp[:, :, 2:4], um, sp[:, :, 4:6], ags, sp[:, :, 6:8], am, sp[:, :, 8:10]]
        return torch.cat(parts, dim=2)

    # --- backbone ------------------------------------------------------------------------------------
    def _causal_bias(self, turns: int) -> torch.Tensor:
        """Turn-level causal mask (N·L, N·L): 0 where turn(key) <= turn(query), else -inf (in the model's
        dtype: torch's CPU attention mis-computes a float64 query with a float32 mask)."""
        length = self.cfg.tokens_per_turn
        turn = torch.arange(turns, device=self.pos_embed.device).repeat_interleave(length)
        allowed = turn[None, :] <= turn[:, None]
        return torch.zeros(allowed.shape, device=allowed.device, dtype=self.pos_embed.dtype).masked_fill(
            ~allowed, -math.inf)

    def _band_layer(self, layer: int, x: torch.Tensor, past: list[KV], band: int) -> tuple[torch.Tensor, list[KV]]:
        """One block of the stream variant over the turns of ``x`` (B, N·L, D) after the ``past`` turns.

        Query turn i attends to the keys/values of turns i-band..i, keys shifted by the learned offset of
        their distance (so a score is q·k + q·r_d); the raw keys/values of the new turns are returned.
        """
        block, length = self.blocks[layer], self.cfg.tokens_per_turn
        q, k, v = block.attn.heads_qkv(block.norm1(x))
        heads = q.shape[1]
        offsets = self.turn_keys[layer].view(self.cfg.max_turns, heads, 1, -1)
        new = list(zip(k.split(length, 2), v.split(length, 2)))
        turns = list(past) + new
        outs = []
        for i in range(len(new)):
            current = len(past) + i
            first = max(0, current - band)
            window = turns[first:current + 1]
            # keys of turn j shifted by the offset of its distance current - j (one broadcast add)
            distances = torch.arange(current - first, -1, -1, device=offsets.device)
            shift = offsets[distances].transpose(0, 1)  # (H, turns, 1, D/H)
            keys = torch.cat([k for k, _ in window], 2)
            keys = (keys.unflatten(2, (len(window), length)) + shift).flatten(2, 3)
            values = torch.cat([v for _, v in window], 2)
            outs.append(block.attn.attend(q[:, :, i * length:(i + 1) * length], keys, values))
        return block.feed_forward(x + block.attn.merge(torch.cat(outs, 2))), new

    def encode(self, tokens: torch.Tensor, band: int | None = None) -> torch.Tensor:
        """Full-sequence encoding (B, N, L, D) -> head conditions (B, N, L, D).

        Faithful: positions 0..N·L-1 of the window, turn-level causal attention. Stream: positions
        inside each turn, attention to the same and the ``band`` previous turns, relative turn offsets.
        """
        b, turns, length, dim = tokens.shape
        if self.cfg.variant == "faithful":
            if turns > self.cfg.max_turns:
                raise ValueError(f"window of {turns} turns exceeds the {self.cfg.max_turns} learned positions")
            x = self.input_norm(tokens.reshape(b, turns * length, dim) + self.pos_embed[:turns * length])
            bias = self._causal_bias(turns)
            for block in self.blocks:
                x, _ = block(x, bias)
            head_pos = self.head_pos_embed[:turns * length]
        else:
            if band is None or not 0 <= band < self.cfg.max_turns:
                raise ValueError(f"stream band must be in 0..{self.cfg.max_turns - 1}, got {band}")
            x = self.input_norm(tokens + self.pos_embed).reshape(b, turns * length, dim)
            for layer in range(len(self.blocks)):
                x, _ = self._band_layer(layer, x, [], band)
            head_pos = self.head_pos_embed.repeat(turns, 1)
        return (self.norm(x) + head_pos).view(b, turns, length, dim)

    def encode_next_turn(self, tokens: torch.Tensor, past: list[list[KV]]) -> tuple[torch.Tensor, list[KV]]:
        """Encode one turn (B, 1, L, D) after cached turns; returns its conditions and new keys/values.

        ``past[l]`` holds, for layer l, the (k, v) of the earlier turns the current turn attends to,
        oldest first: faithful = every turn of the (still growing) window, which therefore sits at
        window index ``len(past[l])``; stream = the band of previous turns, at distances
        ``len(past[l])``, ..., 1.
        """
        b, _, length, dim = tokens.shape
        cached = len(past[0])
        new_kv = []
        if self.cfg.variant == "faithful":
            window = slice(cached * length, (cached + 1) * length)
            x = self.input_norm(tokens.reshape(b, length, dim) + self.pos_embed[window])
            for layer, block in enumerate(self.blocks):
                x, kv = block(x, None, concat_past(past[layer]))
                new_kv.append(kv)
            head_pos = self.head_pos_embed[window]
        else:
            x = self.input_norm(tokens.reshape(b, length, dim) + self.pos_embed)
            for layer in range(len(self.blocks)):
                x, (kv,) = self._band_layer(layer, x, past[layer], cached)
                new_kv.append(kv)
            head_pos = self.head_pos_embed
        return (self.norm(x) + head_pos).view(b, 1, length, dim), new_kv

    # --- training ------------------------------------------------------------------------------------
    def forward(self, user_speech: torch.Tensor, user_motion: torch.Tensor, agent_speech: torch.Tensor,
                agent_motion: torch.Tensor, user_valid: torch.Tensor | None = None,
                agent_valid: torch.Tensor | None = None) -> torch.Tensor:
        """Training loss of a batch of clips; inputs (B, N·F, ·) cover N whole turns.

        One mask ratio per batch r ~ N(1, 0.25) truncated to [0.7, 1]; ceil(N·F·r) agent frames per
        clip masked at random over all turns; each user token dropped to null with p = cfg_dropout;
        the stream variant draws its band uniformly from 0..max_turns-1 per batch. Loss only on masked
        frames.

        ``user_valid`` / ``agent_valid`` (B, N·F) bool (layouts with a validity column, see
        :mod:`models.timar.layouts`): an invalid user motion frame becomes the null token, an invalid agent
        frame is [MASK] as input and never a loss target (loss on masked and valid frames; 0 when none).
        """
        cfg = self.cfg
        b, total, _ = agent_motion.shape
        frames = cfg.frames_per_turn
        turns = total // frames

        def per_turn(x: torch.Tensor) -> torch.Tensor:
            return x.reshape(b, turns, frames, x.shape[-1])

        masked = self.training_mask(b, total, agent_motion.device)
        user_null = torch.rand(b, turns, 2 * frames, device=agent_motion.device) < cfg.cfg_dropout
        shown_masked, target = masked, masked
        if user_valid is not None:
            user_null[..., frames:] |= ~user_valid.view(b, turns, frames)
        if agent_valid is not None:
            shown_masked, target = masked | ~agent_valid, masked & agent_valid
        tokens = self.turn_tokens(per_turn(user_speech), per_turn(user_motion), per_turn(agent_speech),
                                  per_turn(agent_motion), shown_masked.view(b, turns, frames), user_null)
        band = int(torch.randint(0, cfg.max_turns, (1,)).item()) if cfg.variant == "stream" else None
        z = self.encode(tokens, band)[:, :, self.agent_slice].reshape(b, total, -1)
        if not target.any():  # every masked frame invalid: nothing to learn from this batch
            return z.sum() * 0.0
        return self.diffusion_loss(z[target], self.normalize_motion(agent_motion[target]))

    def training_mask(self, batch: int, total: int, device: torch.device | str = "cpu") -> torch.Tensor:
        """(batch, total) bool: ceil(total·r) random agent frames per clip, one r per batch."""
        cfg = self.cfg
        ratio = nn.init.trunc_normal_(torch.empty(1), mean=cfg.mask_ratio_mean, std=cfg.mask_ratio_std,
                                      a=cfg.mask_ratio_min, b=1.0).item()
        order = torch.rand(batch, total, device=device).argsort(dim=1)
        masked = torch.zeros(batch, total, dtype=torch.bool, device=device)
        return masked.scatter_(1, order[:, :math.ceil(total * ratio)], True)

    def diffusion_loss(self, cond: torch.Tensor, x0: torch.Tensor) -> torch.Tensor:
        """Mean over tokens of (MSE exp + MSE jaw + MSE pose of the x0 prediction) + VB term (other layouts:
        the MSE of each of their loss groups, :mod:`models.timar.layouts`).

        ``x0`` is in the model's units (normalised motion).

        Every condition is used ``diffusion_batch_mul`` times with independent timesteps and noise.
        """
        mul = self.cfg.diffusion_batch_mul
        cond, x0 = cond.repeat(mul, 1), x0.repeat(mul, 1)
        t = torch.randint(0, self.train_diffusion.num_steps, (x0.shape[0],), device=x0.device)
        xt = self.train_diffusion.q_sample(x0, t, torch.randn_like(x0))
        out = self.head(xt, t, cond)
        err = (out[:, :x0.shape[1]] - x0) ** 2
        mse = sum(err[:, g].mean(-1) for g in self.loss_groups)
        return (mse + self.train_diffusion.vb_term(out, x0, xt, t)).mean()

    # --- sampling ------------------------------------------------------------------------------------
    @torch.no_grad()
    def sample_frames(self, cond: torch.Tensor, generator: torch.Generator | Sequence[torch.Generator],
                      cfg_scale: float = 1.0, temperature: float = 1.0, clamp_variance: bool = True) -> torch.Tensor:
        """Agent frames (F, 56), original units, from conditions (1, F, D), or (2, F, D) = (conditional,
        unconditional).

        With guidance the x0 prediction is ``u + s·(c − u)`` and the variance that of the
        conditional branch; with one condition row (s = 1) the head runs once per step.
        ``clamp_variance`` keeps the variance interpolation in its range [-1, 1] (see
        :meth:`GaussianDiffusion.sample`). Several streams at once: ``cond`` (S, branches, F, D) with a list
        of S generators gives (S, F, 56), each stream's noise drawn from its own generator.
        """
        streams = cond.shape[0] if cond.dim() == 4 else 1
        shape = (streams,) if cond.dim() == 4 else ()
        cond = cond.flatten(0, 1) if cond.dim() == 4 else cond  # (streams·branches, F, D), stream-major
        branches, frames = cond.shape[0] // streams, cond.shape[1]
        channels = self.cfg.motion_dim
        embedded = self.head.cond_embed(cond.reshape(cond.shape[0] * frames, -1))
        timesteps = self.sample_diffusion.timestep_map.to(cond.device)
        # every step's modulation in one pass: (steps, streams·branches·frames, ·)
        modulation = self.head.modulation(self.head.time_embed(timesteps)[:, None] + embedded)
        if branches == 1:
            def denoise(x: torch.Tensor, i: int) -> torch.Tensor:
                return self.head.denoise_modulated(x.reshape(-1, channels), modulation.at(i)).view(*x.shape[:-1], -1)
        else:
            def denoise(x: torch.Tensor, i: int) -> torch.Tensor:
                each = x.reshape(streams, 1, frames, channels).expand(-1, 2, -1, -1).reshape(-1, channels)
                out = self.head.denoise_modulated(each, modulation.at(i)).view(streams, 2, frames, -1)
                c, u = out[:, 0], out[:, 1]
                guided = u[..., :channels] + cfg_scale * (c[..., :channels] - u[..., :channels])
                return torch.cat([guided, c[..., channels:]], dim=-1).view(*x.shape[:-1], -1)

        x = self.sample_diffusion.sample(denoise, (*shape, frames, channels), generator, temperature, cond.device,
                                         clamp_variance)
        return self.denormalize_motion(x)


def count_parameters(cfg: TimarConfig) -> int:
    """Trainable parameters of a configuration (built on the meta device: no memory is allocated)."""
    with torch.device("meta"):
        model = TimarModel(cfg)
    return sum(p.numel() for p in model.parameters() if p.requires_grad)
