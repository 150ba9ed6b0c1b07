"""Shipped StyGazeTalk checkpoints (package data): the tiny SE-64 style encoder and generator."""
