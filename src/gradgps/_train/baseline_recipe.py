"""What decides a trained comparison model, and the labelled data it is trained on.

:class:`BaselineRecipe` (data, seeds, budget, stopping and the sensor-grid
options) is shared by every trained baseline (:mod:`gradgps._train.baselines`)
and the channel GRAD (:mod:`gradgps._train.channel_grad`); its hash keys their
caches (:func:`gradgps._train.cache.baseline_dir`). :func:`labelled_fixes` and
:func:`labelled_segments` inject a split the way the recipe says.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict, cast

import numpy as np
import pandas as pd

from .._baselines.base import Segment, segments
from .._data.inject import inject_grad, inject_sensor_grid, with_accel_mps2, with_fix_speed
from .._exceptions import ConfigError
from .._tracks.track import ColumnMap, to_fixes

__all__ = [
    "PROTOCOL_INPUTS",
    "SENSOR_EXTRA",
    "WINDOW",
    "BaselineRecipe",
    "inputs_for",
    "labelled_fixes",
    "labelled_segments",
    "sensor_channels",
    "sensor_table",
    "splits",
]

PROTOCOL_INPUTS = {"grad": "position", "sensor-grid": "sensor"}
SENSOR_EXTRA = ["accel_x_mps2", "gyro_z_dps"]
WINDOW = 20


class LoopSettings(TypedDict):
    """The training loop's settings a :class:`BaselineRecipe` fixes (``TrainConfig`` keywords)."""

    max_samples_per_epoch: int
    time_budget_s: float
    seed: int
    patience: int
    learning_rate: float
    max_epochs: int


@dataclass(frozen=True)
class BaselineRecipe:
    """Everything that decides a trained baseline; its hash keys the cache.

    The defaults are GRAD's (:class:`gradgps._train.grad.GradTrainingSet`
    and ``train_grad``'s settings); ``--quick`` benchmarks shrink them.
    """

    seeds: tuple[int, ...] = tuple(range(101, 111))
    val_seed: int = 7
    time_budget_s: float = 180.0
    max_epochs: int = 400
    patience: int = 25
    learning_rate: float = 3e-3
    batch_size: int = 256
    max_samples_per_epoch: int = 100_000
    window: int = WINDOW
    seed: int = 0
    #: sensor-grid only: the row trained on (``mixed``: one model for all rows;
    #: a row name: a per-row experiment), how ``constant`` faults are written
    #: (:data:`gradgps._data.inject.CONSTANT_MODES`), and whether the speed
    #: derived from the fixes is a second speed channel (input ``sensor-fix``).
    row: str = "mixed"
    constant: str = "stuck"
    fix_speed: bool = False

    def loop_settings(self) -> LoopSettings:
        """The training loop's settings this recipe fixes (``TrainConfig`` keywords)."""
        # the TypedDict's keys are the recipe's field names
        return cast(
            LoopSettings, {name: getattr(self, name) for name in LoopSettings.__annotations__}
        )


def inputs_for(protocol: str, recipe: BaselineRecipe | None = None) -> str:
    """The input kind the baselines read under ``protocol`` (and the recipe's options)."""
    if protocol not in PROTOCOL_INPUTS:
        raise ConfigError(
            f"unknown protocol {protocol!r}; choose one of {', '.join(PROTOCOL_INPUTS)}"
        )
    if protocol == "sensor-grid" and recipe is not None and recipe.fix_speed:
        return "sensor-fix"
    return PROTOCOL_INPUTS[protocol]


def sensor_channels(recipe: BaselineRecipe | None) -> list[str]:
    """Extra fixes channels a sensor-grid detector reads (besides ``speed``)."""
    fix = ["speed_fix_mps"] if recipe is not None and recipe.fix_speed else []
    return [*fix, *SENSOR_EXTRA]


def sensor_table(table: pd.DataFrame, recipe: BaselineRecipe | None) -> pd.DataFrame:
    """``table`` with, under ``fix_speed``, the speed derived from the fixes (before injection)."""
    return with_fix_speed(table) if recipe is not None and recipe.fix_speed else table


def labelled_fixes(
    table: pd.DataFrame,
    protocol: str,
    seed: int | None,
    scale: float = 1.0,
    recipe: BaselineRecipe | None = None,
    row: str | None = None,
) -> tuple[pd.DataFrame, np.ndarray, pd.DataFrame]:
    """``(fixes, label_anomaly per row, labelled table)``; ``seed=None`` gives the clean fixes.

    Under ``sensor-grid`` the row is ``row`` (default: the recipe's, ``mixed``
    without one), written with the recipe's ``constant`` mode and channels.
    """
    cmap: ColumnMap = to_fixes(table).attrs["columns"]
    grid = protocol == "sensor-grid"
    channels = sensor_channels(recipe) if grid else []
    source = sensor_table(table, recipe) if grid else table
    if seed is None:
        clean = with_accel_mps2(source) if grid else source
        fixes = to_fixes(clean, cmap, channels=channels)
        return fixes, np.zeros(len(fixes), np.int64), clean
    if protocol == "grad":
        labelled = inject_grad(table, seed=seed, scale=scale, columns=cmap)
    else:
        labelled = inject_sensor_grid(
            source,
            row=row or (recipe.row if recipe is not None else "mixed"),
            seed=seed,
            scale=scale,
            columns=cmap,
            constant=recipe.constant if recipe is not None else "stuck",
        )
    fixes = to_fixes(labelled, cmap, channels=channels)
    return fixes, labelled["label_anomaly"].to_numpy(np.int64), labelled


def labelled_segments(
    table: pd.DataFrame, protocol: str, seeds: Sequence[int], recipe: BaselineRecipe | None = None
) -> tuple[list[Segment], list[np.ndarray]]:
    """Segments and their 0/1 labels of ``table`` injected with every seed."""
    segs: list[Segment] = []
    labels: list[np.ndarray] = []
    for seed in seeds:
        fixes, truth, _ = labelled_fixes(table, protocol, seed, recipe=recipe)
        for seg in segments(fixes, inputs_for(protocol, recipe))[0]:
            segs.append(seg)
            labels.append(truth[seg.rows])
    return segs, labels


def splits(dataset: str, data_dir: str | Path | None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The data set's train and validation splits."""
    from .._data.datasets import load_dataset

    return (
        load_dataset(dataset, "train", data_dir=data_dir),
        load_dataset(dataset, "validation", data_dir=data_dir),
    )
