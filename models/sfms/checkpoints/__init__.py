"""Shipped SFMS checkpoints (package data), tiny tokenizer + predictor each:

- ``sfms-tiny.pt``: trained on the embedded corpus v1, ``synthetic`` (speech = log-mel of the waveform, 32 bins);
- ``sfms-tiny-v2.pt``: the same recipe trained on ``synthetic-v2`` (``--dataset synthetic-v2``);
- ``sfms-tiny-channel-v2.pt``: per-channel keyframe allocation (``--mask-sharing channel``, the paper's §V-B),
  otherwise the ``sfms-tiny-v2.pt`` recipe; loaded by ``--model sfms-channel``;
- ``sfms-tiny-l2l.pt``: trained on the embedded corpus written in the Learning2Listen layout (speech =
  the layout's shipped 128-bin mel rows, 4 per frame, at 30 fps).
"""
