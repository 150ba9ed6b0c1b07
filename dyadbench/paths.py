"""Where dyadbench keeps generated data: ``$DYADBENCH_CACHE`` or the user's cache directory."""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs


def cache_dir() -> Path:
    """Root of dyadbench's cache (generated corpora, derived features). Created on demand."""
    root = os.environ.get("DYADBENCH_CACHE")
    path = Path(root) if root else Path(platformdirs.user_cache_dir("dyadbench"))
    path.mkdir(parents=True, exist_ok=True)
    return path
