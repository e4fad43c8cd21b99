"""The real validation drives, positions only (or with speed, heading), at a rate: what the
tuning scripts loop over.

Never the test splits. Shared by ``false_positive_places.py``, ``held_offsets.py``
and ``tried/lagged_verdict_check.py``.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._eval.robustness import _variant_columns, decimate
from gradgps._tracks.track import ColumnMap, to_fixes

DATASETS = ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada")


def validation_positions(
    period_s: float | None,
    data_dir: str | None = None,
    *,
    keep_native: bool = False,
    variant: str = "positions",
) -> Iterator[tuple[str, pd.DataFrame, list[str], ColumnMap, np.ndarray]]:
    """Per data set with a validation split: ``(name, table, columns, column map, ordinary)``.

    ``table`` holds t, lat, lon (and the track; with ``variant`` ``+speed`` or
    ``+speed+heading`` those columns too, data sets without them left out) at the
    native rate (``period_s`` None) or decimated to one fix per ``period_s``; a data
    set already at that rate is skipped unless ``keep_native``. ``ordinary`` marks
    its rows without a real ``glitch``.
    """
    for name in DATASETS:
        table = load_dataset(name, "validation", data_dir=data_dir)
        picked = _variant_columns(table, to_fixes(table).attrs["columns"], variant)
        if picked is None:  # every data set has positions; not all a speed or heading
            continue
        cols, cmap = picked
        data = table[cols] if period_s is None else decimate(table[cols], cmap, period_s)
        if period_s is not None and len(data) == len(table) and not keep_native:
            continue  # natively at that rate
        glitch = (
            table["glitch"].to_numpy() == 1 if "glitch" in table else np.zeros(len(table), bool)
        )
        yield name, data, cols, cmap, ~glitch[table.index.get_indexer(data.index)]
