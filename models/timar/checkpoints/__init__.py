"""Shipped TIMAR checkpoints (package data): ``timar-tiny.pt`` and ``timar-stream-tiny.pt`` (trained on
the embedded corpus v1, ``synthetic``) ``timar-tiny-v2.pt`` (the same recipe on ``synthetic-v2``) and ``timar-tiny-seamless.pt`` (``timar`` on the
``seamless`` layout, trained on the synthetic corpus written in it; :mod:`models.timar.layouts`)."""
