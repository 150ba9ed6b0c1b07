"""TIMAR: causal turn-level interleaved masked autoregression with a per-token diffusion head.

``timar`` is the faithful model (window-indexed positions, turn-level causal attention, an exact
key/value cache while the context window is still growing); ``timar-stream`` is the streaming-native
variant (per-turn sliding band, positions that never shift, an exact key/value cache at every turn).
Factories: :mod:`models.timar.registry`; training: ``dyadbench train timar`` (:mod:`models.timar.cli`).
"""
