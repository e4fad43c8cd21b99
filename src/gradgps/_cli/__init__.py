"""The ``gradgps`` command line.

One module per command under this package; this file only builds the group
and lists the commands. Heavy imports happen inside commands so
``gradgps --help`` stays fast.
"""

from __future__ import annotations

import click

from .bench import bench
from .calibrate import calibrate
from .demo import demo
from .detect import detect
from .detect_fleet import detect_fleet
from .errors import ErrorReportingGroup
from .export import export
from .info import info
from .inject import inject
from .serve_redis import serve_redis
from .simulate import simulate
from .train import train
from .tune_rema import tune_rema

__all__ = ["main"]


@click.group(cls=ErrorReportingGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="gradgps")
def main() -> None:
    """Find, classify and repair faults in vehicle GPS and sensor streams (GRAD)."""


main.add_command(bench)
main.add_command(calibrate)
main.add_command(demo)
main.add_command(detect)
main.add_command(detect_fleet)
main.add_command(export)
main.add_command(info)
main.add_command(inject)
main.add_command(serve_redis)
main.add_command(simulate)
main.add_command(train)
main.add_command(tune_rema)
