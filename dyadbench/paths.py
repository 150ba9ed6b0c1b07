"""Where dyadbench keeps generated data: ``$DYADBENCH_CACHE`` or the user's cache directory."""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

CACHE_ENV = "DYADBENCH_CACHE"


def cache_location() -> tuple[Path, str]:
    """The cache folder (not created) and how messages name it: the environment variable when it is set."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root), f"{CACHE_ENV}={root}"
    path = Path(platformdirs.user_cache_dir("dyadbench"))
    return path, f"cache folder {path} (set {CACHE_ENV} to use another)"


def cache_dir() -> Path:
    """Root of dyadbench's cache (generated corpora, derived features). Created on demand; a path that
    cannot be a writable folder is a :class:`~dyadbench.errors.ConfigError` naming it."""
    path, label = cache_location()
    if not os.path.isdir(path):
        from dyadbench.outputs import check_folder  # noqa: PLC0415  (outputs imports this module)

        check_folder(path, label)
        path.mkdir(parents=True, exist_ok=True)
    return path
