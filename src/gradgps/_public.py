"""How the public modules claim their names (``gradgps.Detector``, ``gradgps.simulate.simulate_drive``)."""

from __future__ import annotations

from collections.abc import Iterable, MutableMapping
from types import FunctionType
from typing import Any

__all__ = ["claim"]


def claim(namespace: MutableMapping[str, Any], names: Iterable[str]) -> None:
    """Make the curated classes and functions of a public module report that module.

    ``gradgps.Detector``, not ``gradgps._grad.detector.Detector``: help texts
    then name what users import, and pickle finds the class there.
    """
    module = str(namespace["__name__"])
    for name in names:
        obj = namespace[name]
        if isinstance(obj, type | FunctionType) and obj.__module__.startswith("gradgps._"):
            obj.__module__ = module
