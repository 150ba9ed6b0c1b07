"""SFMS keyframe allocation: per-channel (mask_sharing = "channel", the paper's) next to the shared mask.

The constructed signal: channel A steps 0 → 1 between frames 9 and 10, channel B between 29 and 30, every
other channel is constant. With k = 2 keyframes and piecewise-linear inpainting held at the ends, the
only zero-error placement of a step channel is the two frames around its step (hand-derived: frames
before the first keyframe are held, so it must be ≤ 9; after the last, so it must be ≥ 10; the linear
segment between them is exact only if they are adjacent), so each channel's keyframes must be its own
{9, 10} / {29, 30}; one shared pair cannot serve both (a shared mask needs 4 frames).
"""

import numpy as np
import pytest
import torch
from torch import nn

from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.synth.corpus import make_clips
from dyadbench.training.checkpoint import save_checkpoint
from models.sfms.bundle import PREDICTOR_MODEL, SFMS, load_sfms, load_tokenizer
from models.sfms.channel_tokens import gather_tokens, scatter_tokens
from models.sfms.config import predictor_preset, tokenizer_preset
from models.sfms.placement import optimal_placement_mse, optimal_positions, per_channel_optimal_mse
from models.sfms.predictor import SFMSPredictor, class_weights, predictor_losses
from models.sfms.registry import build_sfms, shipped
from models.sfms.tokenizer import SFMSTokenizer
from models.sfms.topk import gumbel_soft_topk

torch.set_num_threads(1)
A, B, STEP_A, STEP_B = 0, 1, 10, 30
SMALL = dict(width=32, heads=2, ffn=64, pe_dim=8)


def steps_window(dim: int = 56) -> torch.Tensor:
    m = torch.zeros(1, 48, dim)
    m[0, STEP_A:, A] = 1.0
    m[0, STEP_B:, B] = 1.0
    return m


class StepScorer(nn.Module):
    """A hand-set Φ_score: s_{t,c} = |m_{t,c} − m_{t−1,c}| + |m_{t+1,c} − m_{t,c}| (zero-padded), per channel
    or summed over channels (shared)."""

    def __init__(self, per_channel: bool):
        super().__init__()
        self.per_channel = per_channel

    def forward(self, m: torch.Tensor) -> torch.Tensor:
        jump = (m[:, 1:] - m[:, :-1]).abs()
        s = nn.functional.pad(jump, (0, 0, 1, 0)) + nn.functional.pad(jump, (0, 0, 0, 1))
        return s if self.per_channel else s.sum(-1)


def tokenizer(sharing: str, **over) -> SFMSTokenizer:
    torch.manual_seed(0)
    cfg = tokenizer_preset("tiny", **{**SMALL, "keyframes": 2, "suppression_radius": 0, "mask_sharing": sharing,
                                      **over})
    return SFMSTokenizer(cfg).eval()


def test_oracle_places_each_channels_keyframes_at_its_own_step():
    w = steps_window(2)[0].numpy().astype(np.float64)
    assert optimal_positions(w[:, [A]], 2).tolist() == [STEP_A - 1, STEP_A]
    assert optimal_positions(w[:, [B]], 2).tolist() == [STEP_B - 1, STEP_B]
    assert per_channel_optimal_mse(w, 2) == 0.0
    assert optimal_placement_mse(w, 2) > 0.0  # one shared pair cannot serve both steps
    assert optimal_placement_mse(w, 4) == 0.0
    assert optimal_positions(w, 4).tolist() == [9, 10, 29, 30]


def test_per_channel_selection_picks_each_channels_own_keyframes():
    tok = tokenizer("channel")
    tok.scorer = StepScorer(per_channel=True)
    mask = tok.select(steps_window())
    assert mask.shape == (1, 48, 56)
    assert torch.nonzero(mask[0, :, A]).flatten().tolist() == [STEP_A - 1, STEP_A]
    assert torch.nonzero(mask[0, :, B]).flatten().tolist() == [STEP_B - 1, STEP_B]
    assert (mask.sum(1) == 2).all()  # the budget: k keyframes in every channel
    classes, kf, codes = tok.encode(steps_window())
    assert torch.equal(kf, mask > 0.5) and torch.equal(classes > 0, kf) and torch.equal(codes >= 0, kf)


def test_shared_selection_gives_every_channel_one_mask():
    tok = tokenizer("frame")
    tok.scorer = StepScorer(per_channel=False)
    mask = tok.select(steps_window())
    assert mask.shape == (1, 48)
    # summed scores: frames 9, 10, 29, 30 all score 1; top-2 with ties to the lower index
    assert torch.nonzero(mask[0]).flatten().tolist() == [STEP_A - 1, STEP_A]


def test_training_masks_are_independent_per_channel():
    """Algorithm 1 runs per column: exactly k per channel, and one channel's logits never move another's mask."""
    tok = tokenizer("channel", keyframes=3)
    logits = torch.randn(2, 48, 56, generator=torch.Generator().manual_seed(0))
    r, hard, hot = tok.allocate(gumbel_soft_topk, logits, 3, 0.5, generator=torch.Generator().manual_seed(1))
    assert hard.shape == (2, 48, 56) and (hard.sum(1) == 3).all()
    assert torch.allclose(hot.sum(1), torch.full((2, 56), 3.0))
    bumped = logits.clone()
    bumped[:, :, B] += 100.0 * torch.randn(2, 48, generator=torch.Generator().manual_seed(2))
    _, hard2, _ = tok.allocate(gumbel_soft_topk, bumped, 3, 0.5, generator=torch.Generator().manual_seed(1))
    keep = [c for c in range(56) if c != B]
    assert torch.equal(hard[..., keep], hard2[..., keep]) and not torch.equal(hard[..., B], hard2[..., B])
    big = torch.zeros(1, 48, 56)
    big[0, STEP_A, A] = big[0, STEP_B, B] = 1e4
    _, hard3, _ = tok.allocate(gumbel_soft_topk, big, 1, 0.5, generator=torch.Generator().manual_seed(3))
    assert hard3[0, STEP_A, A] == 1 and hard3[0, STEP_B, B] == 1


def test_per_channel_gradient_reaches_every_channel_score():
    tok = tokenizer("channel").train()
    losses = tok(torch.randn(2, 48, 56), generator=torch.Generator().manual_seed(0))
    losses["loss"].backward()
    assert torch.isfinite(losses["loss"]) and losses["codes"].numel() == 2 * tok.cfg.gumbel_samples * 2 * 56
    grad = tok.scorer.head.weight.grad  # (d, W): one row per channel's score
    assert grad.shape == (56, 32) and (grad.abs().sum(1) > 0).all()


def test_per_channel_inpainter_reads_only_keyframe_values():
    tok = tokenizer("channel")
    m = torch.randn(1, 48, 56, generator=torch.Generator().manual_seed(0))
    hard = tok.select(m)
    other = torch.where(hard > 0.5, m, torch.randn(1, 48, 56, generator=torch.Generator().manual_seed(1)))
    with torch.no_grad():
        a, b = tok.reconstruct_with(m, hard, hard)[0], tok.reconstruct_with(other, hard, hard)[0]
        assert torch.equal(a, b)
        assert torch.allclose(tok.decode(tok.encode(m)[0]), a, atol=1e-6)


def test_gather_scatter_round_trip():
    mask = torch.zeros(2, 4, 3)
    mask[0, 1, 2] = mask[0, 3, 0] = mask[1, 0, 1] = 1
    flat, frames, chans, pad = gather_tokens(mask)
    assert flat.tolist()[0] == [5, 9] and pad.tolist() == [[False, False], [False, True]]
    assert frames[0].tolist() == [1, 3] and chans[0].tolist() == [2, 0] and frames[1, 0] == 0 and chans[1, 0] == 1
    back = scatter_tokens(torch.tensor([[7, 8], [9, 99]]), flat, pad, (2, 4, 3), fill=-1)
    assert back[0, 1, 2] == 7 and back[0, 3, 0] == 8 and back[1, 0, 1] == 9 and int((back >= 0).sum()) == 3


def test_per_channel_loss_counts_every_channel_token():
    """CE over (frame, channel) tokens: with uniform logits every token's NLL is log V, so the CE is
    log V times the mean class weight of the targets (eq. 14 divides by the token count)."""
    cfg = predictor_preset("tiny", keyframe_loss="bce")
    targets = torch.zeros(2, 8, 3, dtype=torch.long)
    targets[0, 2, 1] = 5
    weights = class_weights(11, 2, 48)
    out = predictor_losses(torch.zeros(2, 8, 3, 11), targets, weights, cfg)
    expected = np.log(11) * (47 * float(weights[0]) + float(weights[5])) / 48
    assert float(out["ce"]) == pytest.approx(expected, rel=1e-6)


def test_shipped_shared_checkpoint_loads_shared_and_encodes_as_before():
    """The committed checkpoint predates the option: it loads as the shared mask and its classes of a fixed
    window are those the shared-only code gave (recorded before per-channel allocation existed)."""
    tok = load_tokenizer(shipped("synthetic"))
    assert tok.cfg.mask_sharing == "frame" and not tok.cfg.per_channel
    t = torch.arange(48.0)
    m = torch.stack([torch.sin(t / (3 + j % 7) + j) for j in range(56)], dim=1)[None] * 1.5
    expected = [84, 0, 0, 0, 0, 0, 0, 0, 0, 166, 0, 0, 166, 0, 0, 126, 0, 0, 117, 0, 0, 116, 0, 0, 116, 0, 0, 116,
                0, 0, 0, 76, 0, 0, 84] + [0] * 13
    assert tok.encode(m)[0][0].tolist() == expected


@pytest.fixture(scope="module", params=["frame", "channel"])
def weights(request, tmp_path_factory):
    torch.manual_seed(0)
    tok = SFMSTokenizer(tokenizer_preset("tiny", **SMALL, keyframes=4, mask_sharing=request.param))
    pred = SFMSPredictor(predictor_preset("tiny", width=32, heads=2, ffn=64, audio_bins=8), 56, tok.cfg.n_classes,
                         tok.cfg.per_channel)
    for block in pred.fusion:
        block.alpha.data.fill_(0.3)
    model = SFMS(tok, pred).eval()
    path = tmp_path_factory.mktemp("sfms") / f"sfms-{request.param}.pt"
    save_checkpoint(path, model_state=model.state_dict(), config=model.config(), meta={"model": PREDICTOR_MODEL})
    return request.param, path


def test_checkpoint_records_the_allocation(weights):
    sharing, path = weights
    model, _ = load_sfms(path)
    assert model.config()["tokenizer"]["mask_sharing"] == sharing
    assert build_sfms(ModelOptions(weights=path)).info.config["tokenizer"]["mask_sharing"] == sharing
    hist = build_sfms(ModelOptions(weights=path)).roller.neutral_history(2)
    assert hist.shape == ((2, 40, 56) if sharing == "channel" else (2, 40))


def test_both_allocations_stream_causally(weights):
    _, path = weights
    clip = make_clips("test", 1, duration_s=4.0)[0]
    check_causal(lambda: build_sfms(ModelOptions(weights=path)), clip, "speaker2", ProtocolConfig(context=1, seed=1), 1)


def test_cli_trains_both_stages_per_channel(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from dyadbench.training.checkpoint import load_checkpoint
    from models.sfms import cli

    train, val = make_clips("train", 2, duration_s=4.0), make_clips("val", 1, duration_s=4.0)
    monkeypatch.setattr(cli, "load_split_clips", lambda *a, **k: (train, val, {"dataset": "generated"}))
    small = ["--set", "width=32", "--set", "heads=2", "--set", "ffn=64", "--steps", "2", "--batch-size", "2",
             "--val-windows", "4", "--threads", "1"]
    tok, full = tmp_path / "tok.pt", tmp_path / "sfms.pt"
    res = CliRunner().invoke(cli.train_tokenizer, small + ["--set", "pe_dim=8", "--keyframes", "3",
                                                           "--mask-sharing", "channel", "--export", str(tok)])
    assert res.exit_code == 0, res.output
    assert load_checkpoint(tok, expect_model="sfms-tokenizer")["config"]["tokenizer"]["mask_sharing"] == "channel"
    res = CliRunner().invoke(cli.train_predictor, small + ["--set", "audio_bins=8", "--tokenizer", str(tok),
                                                           "--export", str(full)])
    assert res.exit_code == 0, res.output
    model, _ = load_sfms(full)
    assert model.predictor.channels == 56 and model.tokenizer.cfg.per_channel


def test_the_shipped_per_channel_checkpoint_loads_as_sfms_channel():
    from models.sfms.registry import CHANNEL_STEM, build_sfms_channel

    path = shipped("synthetic-v2", CHANNEL_STEM)
    assert path.name == "sfms-tiny-channel-v2.pt" and path.is_file()  # a missing shipped file fails
    model = build_sfms_channel(ModelOptions(dataset="synthetic-v2"))
    assert model.info.name == "sfms-channel" and model.info.weights_path == str(path)
    assert model.info.config["tokenizer"]["mask_sharing"] == "channel"
    assert model.roller.neutral_history(1).shape == (1, 40, 56)  # classes per frame and channel
    clip = make_clips("test", 1, duration_s=3.0)[0]
    from dyadbench.protocol.streaming import stream_agent

    out = stream_agent(model, clip, "speaker2", ProtocolConfig(context=1, seed=0)).motion
    assert out.shape == clip.participant("speaker2").motion.shape and np.isfinite(out).all()


def test_sfms_channel_refuses_shared_mask_weights():
    from dyadbench.errors import InputError
    from models.sfms.registry import build_sfms_channel

    shared = shipped("synthetic-v2")
    with pytest.raises(InputError, match="--model sfms") as err:
        build_sfms_channel(ModelOptions(weights=shared))
    assert shared.name in str(err.value)


def test_sfms_channel_without_weights_names_the_command(tmp_path):
    from dyadbench.errors import InputError
    from models.sfms.registry import build_sfms_channel

    with pytest.raises(InputError, match="--mask-sharing channel"):
        build_sfms_channel(ModelOptions(weights=tmp_path / "none.pt"))
