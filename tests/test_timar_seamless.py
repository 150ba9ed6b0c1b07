"""TIMAR on the Seamless Interaction layout: 165 generated columns at 30 frames per turn, causality, the
shipped checkpoint, refusal of a checkpoint of another layout, and a loss that never sees invalid frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from dyadbench.datasets.seamless import SEAMLESS, open_split
from dyadbench.errors import InputError
from dyadbench.protocol.causality import check_causal
from dyadbench.protocol.config import ProtocolConfig
from dyadbench.protocol.interface import ModelOptions
from dyadbench.protocol.streaming import stream_agent
from dyadbench.synth.seamless_writer import write_seamless_split
from dyadbench.training.checkpoint import save_checkpoint
from models.timar.config import preset
from models.timar.data import WindowDataset
from models.timar.frontends import make_frontend
from models.timar.layouts import SEAMLESS as TIMAR_SEAMLESS
from models.timar.layouts import configure_for
from models.timar.model import TimarModel
from models.timar.registry import CHECKPOINT_DIR, build_timar, build_timar_stream, shipped

MICRO = dict(token_dim=16, dim=16, heads=2, depth=2, head_width=16, max_turns=4)


def micro_seamless(seed: int = 0) -> TimarModel:
    torch.manual_seed(seed)
    model = TimarModel(configure_for(preset("tiny", "faithful", **MICRO), TIMAR_SEAMLESS)).eval()
    with torch.no_grad():  # the head starts at zero output; give it weights so outputs depend on inputs
        for p in model.head.parameters():
            p.add_(torch.randn_like(p) * 0.1)
    return model


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("timar-seamless")
    write_seamless_split(out, split="test", clips=2, progress=False, duration_s=4.0)
    return out


@pytest.fixture(scope="module")
def weights(tmp_path_factory) -> Path:
    model = micro_seamless()
    return save_checkpoint(tmp_path_factory.mktemp("w") / "timar-seamless.pt", model_state=model.state_dict(),
                           config=model.cfg.to_dict(), meta={"model": "timar", "data_digest": "test"})


def _clip(root: Path):
    source = open_split(root, "improvised/test")
    return source.load(source.clip_ids()[0])


def test_configuration_of_the_layout():
    cfg = configure_for(preset("tiny"), TIMAR_SEAMLESS)
    assert (cfg.motion_dim, cfg.frames_per_turn, cfg.samples_per_turn) == (165, 30, 16_000)
    assert TIMAR_SEAMLESS.dim == SEAMLESS.dim == 166
    assert TIMAR_SEAMLESS.valid_column == SEAMLESS.components["valid"].start
    assert [s.stop - s.start for s in TIMAR_SEAMLESS.loss_groups] == [128, 3, 34]


def test_streams_165_generated_columns_at_30_frames_per_turn(root, weights):
    clip = _clip(root)
    model = build_timar(ModelOptions(weights=weights, extra={"layout": "seamless"}))
    assert model.info.layout == "seamless"
    out = stream_agent(model, clip, clip.participants[0].name, ProtocolConfig(context=2)).motion
    assert clip.fps == 30.0 and clip.num_frames == 120
    assert out.shape == (120, 166) and np.isfinite(out).all()
    generated = out[:, :165]
    assert generated.shape == (120, 165) and np.all(out[:, 165] == 1.0)
    assert not np.allclose(generated[:30], generated[30:60])  # each 30-frame turn sampled anew


@pytest.mark.parametrize("turn", [0, 2])
def test_causal_through_the_protocol(root, weights, turn):
    clip = _clip(root)
    check_causal(lambda: build_timar(ModelOptions(weights=weights)), clip, clip.participants[1].name,
                 ProtocolConfig(context=2), turn)


def test_shipped_seamless_checkpoint_is_committed_and_picked_for_seamless():
    path = shipped("timar", "seamless")
    assert path == CHECKPOINT_DIR / "timar-tiny-seamless.pt" and path.is_file(), path
    assert path.stat().st_size < 8 * 2**20
    meta = torch.load(path, map_location="cpu", weights_only=True)["meta"]
    assert meta["layout"] == "seamless" and meta["data"]["dataset"] == "seamless"
    assert meta["data"]["split"] == "train" and meta["command"].startswith("dyadbench train timar --dataset seamless")
    model = build_timar(ModelOptions(dataset="seamless", extra={"layout": "seamless"}))
    assert model.info.layout == "seamless" and Path(model.info.weights_path) == path
    assert (model.model.cfg.motion_dim, model.model.cfg.frames_per_turn) == (165, 30)
    # the FLAME corpora keep their checkpoints
    assert shipped("timar", "synthetic") == CHECKPOINT_DIR / "timar-tiny.pt"


def test_checkpoint_of_another_layout_is_refused_naming_the_file(weights):
    flame = shipped("timar", "synthetic")
    with pytest.raises(InputError, match=r"timar-tiny\.pt: this timar checkpoint generates flame56 motion "
                                         r"\(56 dims at 25 fps\); the split is seamless"):
        build_timar(ModelOptions(weights=flame, extra={"layout": "seamless"}))
    with pytest.raises(InputError, match=r"timar-seamless\.pt: .*generates seamless motion .*split is flame56"):
        build_timar(ModelOptions(weights=weights, extra={"layout": "flame56"}))
    # timar-stream ships no seamless checkpoint: its FLAME one is loaded and refused
    with pytest.raises(InputError, match=r"timar-stream-tiny-v2\.pt: .*generates flame56 motion"):
        build_timar_stream(ModelOptions(dataset="seamless", extra={"layout": "seamless"}))


def _batch(seed: int = 3) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    frames = 2 * 30
    return {"user_speech": torch.randn(2, frames, 40, generator=g),
            "user_motion": torch.randn(2, frames, 165, generator=g),
            "agent_speech": torch.randn(2, frames, 40, generator=g),
            "agent_motion": torch.randn(2, frames, 165, generator=g)}


def _loss(model: TimarModel, batch: dict, **valid) -> float:
    torch.manual_seed(11)  # same masks, guidance drops, timesteps and noise in every call
    return model(**batch, **valid).item()


def test_loss_never_sees_invalid_frames():
    model = micro_seamless().train()
    batch = _batch()
    agent_valid = torch.ones(2, 60, dtype=torch.bool)
    agent_valid[:, 30:] = False  # the second turn of each window invalid
    user_valid = torch.ones(2, 60, dtype=torch.bool)
    user_valid[0, :30] = False
    changed = dict(batch)
    changed["agent_motion"] = batch["agent_motion"].clone()
    changed["agent_motion"][:, 30:] = 1e3  # what the model must never see nor fit
    changed["user_motion"] = batch["user_motion"].clone()
    changed["user_motion"][0, :30] = -1e3
    valid = {"agent_valid": agent_valid, "user_valid": user_valid}
    masked = _loss(model, batch, **valid)
    assert np.isfinite(masked) and masked == _loss(model, changed, **valid)
    # without the validity flags the same values change the loss (they are inputs and targets then)
    assert _loss(model, changed) != _loss(model, batch)
    # a batch without one valid agent frame contributes nothing
    assert _loss(model, batch, agent_valid=torch.zeros(2, 60, dtype=torch.bool)) == 0.0


def test_training_windows_carry_validity_and_statistics_use_valid_frames(root):
    cfg = configure_for(preset("tiny", **MICRO), TIMAR_SEAMLESS)
    source = open_split(root, "improvised/test")
    data = WindowDataset(source, make_frontend(cfg, fps=30.0), cfg, stride_turns=1, progress=False)
    item = data[0]
    assert item["agent_motion"].shape == (120, 165) and item["user_speech"].shape == (120, 40)
    assert item["agent_valid"].dtype == torch.bool and item["user_valid"].shape == (120,)
    motion = [source.load(c).participants for c in source.clip_ids()]
    rows = np.concatenate([p.motion[p.motion[:, 165] > 0.5, :165] for ps in motion for p in ps])
    assert len(rows) < sum(len(p.motion) for ps in motion for p in ps)  # the split holds invalid blocks
    mean, _ = data.motion_statistics()
    np.testing.assert_allclose(mean, rows.astype(np.float64).mean(0), rtol=1e-5, atol=1e-6)


def test_layout_checkpoint_only_where_shipped(tmp_path):
    from dyadbench.shipped import shipped_checkpoint  # noqa: PLC0415

    default = shipped_checkpoint(tmp_path, "m", None)
    assert shipped_checkpoint(tmp_path, "m", "seamless") == default  # none shipped: the default, refused later
    (tmp_path / "m-seamless.pt").write_bytes(b"")
    assert shipped_checkpoint(tmp_path, "m", "seamless") == tmp_path / "m-seamless.pt"
    assert shipped_checkpoint(tmp_path, "m", "dualtalk") == default
