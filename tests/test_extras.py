"""Every optional dependency an extra installs is one the code imports."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_io_extra_installs_only_what_the_readers_import() -> None:
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    source = "\n".join(p.read_text() for p in (ROOT / "src" / "gradgps").rglob("*.py"))
    for requirement in extras["io"]:
        name = re.split(r"[<>=\[ ;]", requirement, maxsplit=1)[0].replace("-", "_")
        assert re.search(rf"^\s*(import|from) {name}\b", source, re.M), (
            f"extra 'io' installs {requirement}, which no code imports"
        )
