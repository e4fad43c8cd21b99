"""The command line speaks one language: -o/--output, defaults shown, one line per missing extra."""

from __future__ import annotations

import builtins
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._cli import main


@pytest.mark.parametrize(
    ("args", "module", "extra"),
    [
        (["train", "--dataset", "simulated", "-o", "m"], "torch", "train"),
        (["detect-fleet", "IN", "-o", "OUT"], "dask", "fleet"),
        (
            [
                *("serve-redis", "--url", "redis://127.0.0.1:1/0", "--input-stream", "i"),
                *("--output-stream", "o", "--group", "g", "--consumer", "c"),
            ],
            "redis",
            "fleet",
        ),
    ],
)
def test_missing_extra_is_one_line_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str], module: str, extra: str
) -> None:
    real_import = builtins.__import__
    owners = {"torch": "_train", "dask": "fleet_dask", "redis": "fleet_redis"}

    def without_extra(name: str, *rest: Any, **kw: Any) -> Any:
        # As if the extra were not installed: its module, and gradgps' modules needing it.
        if name.split(".")[0] == module or owners[module] in name:
            raise ModuleNotFoundError(f"No module named '{module}'", name=module)
        return real_import(name, *rest, **kw)

    if args[0] == "detect-fleet":
        folder = tmp_path / "in"
        folder.mkdir()
        (folder / "a.csv").write_text("t,lat,lon\n0,1,2\n")
        args = ["detect-fleet", str(folder), "-o", str(tmp_path / "out")]
    monkeypatch.setattr(builtins, "__import__", without_extra)
    run = CliRunner().invoke(main, args)
    monkeypatch.undo()
    assert run.exit_code == 1, run.output
    assert f"pip install 'gradgps[{extra}]'" in run.output
    assert "Traceback" not in run.output
    assert run.output.strip().count("\n") == 0


def test_output_options_and_defaults_are_consistent() -> None:
    demo = CliRunner().invoke(main, ["demo", "--help"]).output
    assert "-o, --output, --out" in demo
    inject = CliRunner().invoke(main, ["inject", "--help"]).output
    assert "--seed INTEGER" in inject
    assert "[default: 0]" in inject
    detect = CliRunner().invoke(main, ["detect", "--help"]).output
    assert "default: the model's own" in " ".join(detect.split())


def test_info_fits_80_columns_with_start_end_and_warnings(tmp_path: Path) -> None:
    path = tmp_path / "kmh.csv"
    t = np.arange(0.0, 120.0) + 1795428000.0
    frame = pd.DataFrame(
        {"t": t, "lat": 48.1 + 3e-4 * np.arange(120), "lon": 11.5, "speed": 120.0}  # km/h
    )
    frame.to_csv(path, index=False)
    run = CliRunner().invoke(main, ["info", str(path)], env={"COLUMNS": "80"})
    assert run.exit_code == 0, run.output
    assert max(len(line) for line in run.output.splitlines()) <= 80
    assert "2026-11-23 10:00:00" in run.output
    assert "2026-11-23 10:01:59" in run.output
    assert "warning: track 0: reported speed up to 120 m/s" in run.output
