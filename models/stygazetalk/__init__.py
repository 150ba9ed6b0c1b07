"""StyGazeTalk ("Beat on Gaze"): style-aware gaze–head generation from speech, first runnable implementation.

Modules, one job each:

- :mod:`.config` — every spec decision (D1–D39) as a config field; presets ``<size>-<variant>``.
- :mod:`.style_encoder` — Transformer style encoder and NT-Xent; :mod:`.train_style` trains it (stage 1).
- :mod:`.generator` — LSTM (learned h0/c0) or causal-Transformer generator with one-frame-lag windows.
- :mod:`.audio` — window-local log-mel (or local wav2vec) features; :mod:`.normalise` — z-scoring.
- :mod:`.data` — segments, generator window bank, style pairs; :mod:`.train_generator` (stage 2).
- :mod:`.system` — the trained whole (normalisers + frozen SE + generator), one inference window.
- :mod:`.generation` — whole-session sliding-window generation, MPGW-sim seed.
- :mod:`.stream` / :mod:`.registry` — the streaming model and its factory ``build_stygazetalk``.
- :mod:`.checkpoints` — checkpoint files and the shipped weights; :mod:`.evaluator` — the frozen
  style encoder as the versioned CE evaluator of the gaze suite.
- :mod:`.cli` — ``dyadbench train stygazetalk-style`` and ``dyadbench train stygazetalk``.
"""
