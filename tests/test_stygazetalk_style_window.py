"""StyGazeTalk's training style window (D7): the leak-free "past" window never reads a scored target frame,
the literal "motion-window" reading does (so the perturbation test can fail), and "past" with the loss on the
last N outputs is exactly the inference window s = SE(x_{t−M..t−1})."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from dyadbench.errors import ConfigError
from models.stygazetalk.config import get_generator_config, get_style_config
from models.stygazetalk.system import StyGazeTalkSystem
from models.stygazetalk.train_generator import first_scored, style_history, style_window, window_loss

torch.set_num_threads(1)
M, N, F_AUDIO = 50, 25, 40


def _system(style_input: str, loss_outputs: str = "all") -> StyGazeTalkSystem:
    cfg = replace(get_generator_config("tiny-se64"), style_input=style_input, loss_outputs=loss_outputs).validate()
    return StyGazeTalkSystem(cfg, get_style_config("tiny-se64")).eval()


def _captured_style_inputs(system: StyGazeTalkSystem, motion: torch.Tensor, audio: torch.Tensor):
    """(style-encoder input, style vector, loss) of one window_loss call, read by a forward hook."""
    seen = {}
    hook = system.style_encoder.register_forward_hook(
        lambda module, args, out: seen.update(window=args[0].clone(), style=out.clone()))
    try:
        with torch.no_grad():
            loss = window_loss(system, motion, audio)[0]
    finally:
        hook.remove()
    return seen["window"], seen["style"], loss


def _perturb_targets(motion: torch.Tensor, system: StyGazeTalkSystem) -> torch.Tensor:
    """Rows x_{u−1−pre}..x_{u+M−1}: replace every scored target x_{u+f}..x_{u+M−1} by other values."""
    pre = motion.shape[1] - M - 1
    out = motion.clone()
    first_row = pre + 1 + first_scored(system.cfg)
    out[:, first_row:] += 3.0 + torch.randn_like(out[:, first_row:])
    return out


@pytest.mark.parametrize("loss_outputs", ["all", "last-n"])
def test_past_style_window_is_unchanged_when_the_target_frames_change(loss_outputs):
    system = _system("past", loss_outputs)
    gen = torch.Generator().manual_seed(0)
    pre = M - 1  # enough history for every style input
    motion = torch.randn(4, pre + M + 1, 7, generator=gen)
    audio = torch.randn(4, M, F_AUDIO, generator=gen)
    window, style, loss = _captured_style_inputs(system, motion, audio)
    window2, style2, loss2 = _captured_style_inputs(system, _perturb_targets(motion, system), audio)
    assert torch.equal(window, window2) and torch.equal(style, style2)
    assert not torch.isclose(loss, loss2)  # the targets did change what the step trains on


def test_literal_style_window_changes_when_the_target_frames_change():
    system = _system("motion-window")
    gen = torch.Generator().manual_seed(0)
    motion = torch.randn(4, M + 1, 7, generator=gen)  # the literal reading's bank rows (pre = 0)
    audio = torch.randn(4, M, F_AUDIO, generator=gen)
    window, style, _ = _captured_style_inputs(system, motion, audio)
    window2, style2, _ = _captured_style_inputs(system, _perturb_targets(motion, system), audio)
    assert not torch.equal(window, window2)
    assert (style - style2).abs().max() > 1e-3
    # literal = the motion inputs x_{u−1..u+M−2} (D7 as written), M−1 of which are targets
    assert torch.equal(window, motion[:, :-1])


def test_style_windows_by_frame_index():
    # bank rows whose value is the frame index: row j holds x_{u−1−pre+j}; take u = 100
    u = 100
    for style_input, loss_outputs, expected_first in (("motion-window", "all", u - 1),
                                                      ("preceding", "all", u - 1 - M),
                                                      ("past", "all", u - M),
                                                      ("past", "last-n", u + (M - N) - M)):
        cfg = replace(get_generator_config("tiny-se64"), style_input=style_input, loss_outputs=loss_outputs)
        pre = style_history(cfg)
        rows = torch.arange(u - 1 - pre, u + M, dtype=torch.float32)[None, :, None].expand(1, -1, 7)
        window = style_window(cfg, rows)
        assert window.shape == (1, M, 7)
        assert window[0, 0, 0].item() == expected_first and window[0, -1, 0].item() == expected_first + M - 1
    # "past" + last-n = inference: new frames t = u + W, s = SE(x_{t−M..t−1}) (system.next_block)
    cfg = replace(get_generator_config("tiny-se64"), style_input="past", loss_outputs="last-n")
    assert style_history(cfg) == N - 1 and style_history(replace(cfg, loss_outputs="all")) == M - 1


def test_style_window_refuses_rows_without_enough_history():
    cfg = replace(get_generator_config("tiny-se64"), style_input="past")
    with pytest.raises(ValueError, match="needs 49 frames"):
        style_window(cfg, torch.zeros(1, M + 1, 7))
    with pytest.raises(ConfigError, match="style_input"):
        replace(cfg, style_input="future").validate()


def test_past_style_window_through_the_bank_reads_no_target_of_a_segment():
    """End to end on a segment: the leak-free training inputs of a window do not depend on its target
    frames (a perturbation of the segment's frames from u onward), the literal ones do."""
    from models.stygazetalk.data import Segment, build_window_bank

    rng = np.random.default_rng(1)
    motion = rng.normal(size=(400, 7)).astype(np.float32)
    audio = np.zeros(400 * 640, np.float32)
    later = motion.copy()
    later[200:] += 5.0  # frames >= 200 changed
    styles = {}
    for style_input in ("past", "motion-window"):
        system = _system(style_input)
        banks = [build_window_bank([Segment("s", "spk", 0, m, audio)], window=M, stride=25, pre=M - 1,
                                   motion_norm=lambda x: x, audio_features=lambda w: np.zeros((M, F_AUDIO), np.float32))
                 for m in (motion, later)]
        u_of_rows = np.arange(len(banks[0])) * 25 + 50  # grid starts u >= 1 + pre = 50
        row = int(np.flatnonzero(u_of_rows == 200)[0])  # the window whose first target is x_200
        with torch.no_grad():
            styles[style_input] = [system.style(style_window(system.cfg, torch.from_numpy(b.motion[row:row + 1])))
                                   for b in banks]
    assert torch.equal(*styles["past"])
    assert not torch.allclose(*styles["motion-window"])
