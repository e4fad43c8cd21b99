"""``gradgps simulate``: write simulated car drives to CSV or Parquet."""

from __future__ import annotations

from pathlib import Path

import click

from .options import option

__all__ = ["simulate"]

# Above this many tracks a progress bar is worth its screen line.
_PROGRESS_FROM = 20


@click.command()
@option(
    "--minutes",
    type=click.FloatRange(min=0.0, min_open=True, max=1440.0),
    default=30.0,
    help="length of each drive",
)
@option(
    "--rate", "rate_hz", type=click.FloatRange(0.1, 100.0), default=1.0, help="fixes per second"
)
@option("--seed", type=int, default=0, help="same seed, same bytes")
@option(
    "--tracks",
    minimum=1,
    default=1,
    help="number of drives (track ids 0..N-1, start points spread around the origin)",
)
@option("--no-imu", is_flag=True, help="leave out accel_x (m/s^2) and yaw_rate (deg/s)")
@option("-o", "--output", path="file", required=True, help="output file: .csv or .parquet")
def simulate(
    minutes: float, rate_hz: float, seed: int, tracks: int, no_imu: bool, output: Path
) -> None:
    """Simulate realistic car drives (GNSS + optional IMU) and write them to a file."""
    suffix = output.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise click.BadParameter(f"{output}: extension must be .csv or .parquet", param_hint="'-o'")

    from rich.progress import Progress

    from .._data.simulator import simulate_drive, simulate_fleet

    if tracks == 1:
        frame = simulate_drive(minutes, rate_hz, seed, imu=not no_imu)
    elif tracks < _PROGRESS_FROM:
        frame = simulate_fleet(tracks, minutes, rate_hz, seed, imu=not no_imu)
    else:
        with Progress(transient=True) as progress:
            task = progress.add_task("simulating drives", total=tracks)
            frame = simulate_fleet(
                tracks,
                minutes,
                rate_hz,
                seed,
                imu=not no_imu,
                on_track=lambda _: progress.advance(task),
            )
    from .._io.read import write_table

    write_table(frame, output)
    stopped = float((frame["speed"] < 0.5).mean())
    click.echo(
        f"wrote {output}: {tracks} track(s), {len(frame)} fixes, {minutes:g} min at {rate_hz:g} Hz, "
        f"seed {seed}, mean speed {frame['speed'].mean():.1f} m/s, {stopped:.0%} stopped"
    )
