"""Counting the bytes a reader takes from its files: for readers whose buffers are C
memory (expat, ijson's yajl), which tracemalloc does not see, "stopped after about
1 MiB" is checked at the file objects instead."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest


def count_reads(monkeypatch: pytest.MonkeyPatch, module: ModuleType) -> list[int]:
    """Make ``module.open_bytes`` record the size of every ``read`` of the files it opens;
    the list it returns fills as they are read (clear it between reads)."""
    sizes: list[int] = []
    opened = module.open_bytes

    @contextlib.contextmanager
    def counted(where: Path) -> Iterator[Any]:
        with opened(where) as raw:
            real = raw.read

            def read(size: int = -1) -> bytes:
                block = real(size)
                sizes.append(len(block))
                return bytes(block)

            raw.read = read
            yield raw

    monkeypatch.setattr(module, "open_bytes", counted)
    return sizes
