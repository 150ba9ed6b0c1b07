"""Shipped SFMS checkpoint (package data): ``sfms-tiny.pt``, the tiny tokenizer + predictor."""
