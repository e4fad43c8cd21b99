"""One input and one command for the tests that compare the report with ``--geojson``.

Two simulated drives with protocol ``grad`` faults and a low threshold (so the
report has flagged fixes to draw), run through ``gradgps detect --report
--geojson``: the report's tests and its browser test read the same files.
"""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet


def report_and_geojson(folder: Path) -> tuple[Path, Path]:
    """Write the drives to ``folder``, run ``detect --report --geojson``; the two outputs."""
    drives = inject_grad(simulate_fleet(2, 3.0, 1.0, 5), seed=1)
    source = folder / "in.csv"
    drives[["track", "t", "lat", "lon", "speed"]].to_csv(source, index=False)
    report, geojson = folder / "report.html", folder / "out.geojson"
    run = CliRunner().invoke(
        main,
        [
            "detect",
            str(source),
            "--threshold",
            "0.2",
            "--report",
            str(report),
            "--geojson",
            str(geojson),
        ],
    )
    assert run.exit_code == 0, run.output
    return report, geojson
