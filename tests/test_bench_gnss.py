"""``gradgps bench --protocol gnss``: the report's shape on a tiny simulated input (fast)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from gradgps import SpeedGate
from gradgps._data.inject import inject_gnss
from gradgps._data.simulator import simulate_fleet
from gradgps._eval.gnss import GNSS_BIAS, _variant, gnss_cell, gnss_markdown
from gradgps._tracks.track import ColumnMap, to_fixes


def _labelled() -> pd.DataFrame:
    drives = simulate_fleet(2, 12.0, 1.0, seed=11)[["track", "t", "lat", "lon", "speed", "heading"]]
    labelled = inject_gnss(drives.reset_index(drop=True), seed=0)
    labelled["glitch"] = 0
    labelled.loc[5, "glitch"] = 1  # a real glitch: left out of every score
    return labelled


def test_cells_have_every_type_and_the_drift_numbers() -> None:
    labelled = _labelled()
    full: ColumnMap = to_fixes(labelled).attrs["columns"]
    cells = {}
    for variant in ("positions", "+columns"):
        cols, cmap = _variant(labelled, full, variant)
        cells[variant] = gnss_cell(SpeedGate(), labelled, cols, cmap)
    assert cells["positions"]["rows"] == len(labelled) - 1
    for cell in cells.values():
        assert set(cell["types"]) == set(GNSS_BIAS)
        for kind in GNSS_BIAS:
            entry = cell["types"][kind]
            assert entry["episodes"] >= 0
            assert entry["recall"] is None or 0.0 <= entry["recall"] <= 1.0
        drift = cell["types"]["drift"]
        assert drift["episodes"] == len(drift["drift_episodes"]) > 0
        assert {"delay_s", "offset_at_detection_m", "found"} <= set(drift["drift_episodes"][0])
        # The speed gate names no types: precision undefined, never a made-up number.
        assert all(cell["types"][k]["precision"] is None for k in GNSS_BIAS if k != "outage")
    # With the receiver's columns an outage is refused as a no-fix (typed outage): all found.
    outage = cells["+columns"]["types"]["outage"]
    assert outage["episodes"] > 0
    assert outage["recall"] == 1.0
    assert outage["precision"] == 1.0
    assert cells["positions"]["types"]["outage"]["precision"] is None


def test_markdown_has_one_row_per_cell_and_every_type() -> None:
    labelled = _labelled()
    full: ColumnMap = to_fixes(labelled).attrs["columns"]
    cols, cmap = _variant(labelled, full, "+columns")
    cell = {"dataset": "sim", "variant": "+columns", "columns": cols}
    cell.update(gnss_cell(SpeedGate(), labelled, cols, cmap))
    report = {
        "detector": "speed-gate",
        "model": None,
        "machine": "test",
        "seconds": 1.0,
        "seed": 0,
        "cells": [cell],
    }
    json.dumps(report, default=lambda v: v.item())
    lines = gnss_markdown(report, "gradgps bench --protocol gnss")
    cut = next(i for i, line in enumerate(lines) if line.startswith("Drift episodes"))
    table = [line for line in lines[:cut] if line.startswith("| sim |")]
    assert len(table) == 1
    episodes = [line for line in lines[cut:] if line.startswith("| sim |")]
    drift = cell["types"]["drift"]["drift_episodes"]
    assert len(episodes) == (1 if drift else 0)
    if drift:  # one entry per episode: "<offset> m @ <delay> s" or "missed"
        entries = episodes[0].split("|")[4].split(",")
        assert len(entries) == len(drift)
        assert all(("m @" in e) == bool(d["found"]) for e, d in zip(entries, drift, strict=True))
    assert table[0].count("|") == 6 + len(GNSS_BIAS) + 2
    header = next(line for line in lines if line.startswith("| data set |"))
    assert all(kind in header for kind in GNSS_BIAS)
    assert np.isfinite(cell["anomaly"]["f1"])


def test_cli_takes_one_detector() -> None:
    from click.testing import CliRunner

    from gradgps._cli import main

    res = CliRunner().invoke(main, ["bench", "--protocol", "gnss", "--detector", "rema,grad"])
    assert res.exit_code == 2
    assert "one --detector" in res.output
