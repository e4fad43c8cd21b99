"""The one cache of trained models (GRAD and the baselines), in ``$GRADGPS_CACHE``.

A trained model is kept under a key of everything that decides it: the
caller's settings, the package version, and (for real data sets) the names
and sizes of the data files, so a new release, other settings or changed
data train afresh. Default folder: ``~/.cache/gradgps``.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["cache_root", "cached_path"]


def cache_root() -> Path:
    """``$GRADGPS_CACHE``, else ``~/.cache/gradgps``."""
    return Path(os.environ.get("GRADGPS_CACHE", Path.home() / ".cache" / "gradgps"))


def cached_path(
    folder: str,
    name: str,
    settings: Mapping[str, Any],
    dataset: str,
    data_dir: str | Path | None,
) -> Path:
    """``cache_root()/folder/name-DIGEST``, DIGEST hashing ``settings``, version and data files."""
    from .._data.datasets import find_data_dir
    from .._version import __version__

    key: dict[str, Any] = {"version": __version__, **settings}
    if dataset != "simulated":
        key["files"] = sorted(
            (p.name, p.stat().st_size) for p in find_data_dir(data_dir).glob("*.csv")
        )
    digest = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return cache_root() / folder / f"{name}-{digest}"
