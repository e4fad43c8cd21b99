"""Loading a benchmark script (``benchmarks/...``, not a package) as a module, for tests
of its pure helpers."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

_ROOT = Path(__file__).resolve().parents[1]


def load_script(relative: str) -> ModuleType:
    """The script at ``relative`` (from the repository root), executed as a module."""
    path = _ROOT / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    # Registered before it runs: a dataclass looks its module up by name while the
    # class is built.
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
