"""Shipped TIMAR checkpoints (package data): ``timar-tiny.pt`` and ``timar-stream-tiny.pt`` (trained on
the embedded corpus v1, ``synthetic``) and ``timar-tiny-v2.pt`` (the same recipe on ``synthetic-v2``)."""
