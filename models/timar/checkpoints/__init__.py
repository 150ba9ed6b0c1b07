"""Shipped TIMAR checkpoints (package data): ``timar-tiny.pt`` and ``timar-stream-tiny.pt``."""
