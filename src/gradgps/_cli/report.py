"""``--report`` / ``--plots`` of ``gradgps detect`` and ``gradgps demo``: shared by both commands."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import click

__all__ = ["write_report_outputs"]


def write_report_outputs(
    report_path: Path | None,
    plots_dir: Path | None,
    fixes: Any,
    result: Any,
    detector: Any,
    elapsed_s: float,
    source: str,
    extra_summary: Mapping[str, str] | None = None,
    events: Any = None,
    warnings: Sequence[str] = (),
    time_text: Any = None,
    geojson: Any = None,
    thinned: Any = None,
) -> None:
    """Write the HTML report and/or the PNG figures and say where they went."""
    if report_path is None and plots_dir is None:
        return
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise click.ClickException(
            "--report and --plots need matplotlib: pip install 'gradgps[report]'"
        ) from None
    from .._run.report import ReportInputs, write_plots, write_report

    inputs = ReportInputs(
        fixes=fixes,
        result=result,
        params=detector.model_.params,
        source=source,
        model=f"{detector.model_.path} (sha256 {detector.model_.checksum[:12]})",
        elapsed_s=elapsed_s,
        extra_summary=dict(extra_summary or {}),
        events=events,
        warnings=list(warnings),
        time_text=time_text,
        geojson=geojson,
        thinned=thinned,
    )
    if report_path is not None:
        path = write_report(inputs, report_path)
        click.echo(f"report: {path} ({path.stat().st_size / 1e6:.2f} MB, open it in a browser)")
    if plots_dir is not None:
        paths = write_plots(inputs, plots_dir)
        click.echo(f"plots: {len(paths)} PNG files in {plots_dir}")
