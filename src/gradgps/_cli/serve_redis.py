"""``gradgps serve-redis``: a live-fleet worker on a Redis Streams consumer group.

Reads fixes from the input stream (``vehicle_id``, ``t``, ``lat``, ``lon``,
optional ``speed``, ``heading`` and numeric channels), appends one result per
message to the output stream and only then acknowledges it. Start as many as
needed with distinct ``--consumer`` names; a killed one restarted under its
name (or replaced by the others after ``--lease-ms``) continues with no lost
and no duplicated result. See :mod:`gradgps._run.fleet_redis` and docs/fleet.md.
Stops cleanly on SIGTERM or Ctrl-C (finishing the transaction in flight).
"""

from __future__ import annotations

import signal
import time
from pathlib import Path
from types import FrameType

import click

from .options import model_options, option

__all__ = ["serve_redis"]

# Seconds between two status lines on stderr.
_STATUS_EVERY_S = 10.0


@click.command("serve-redis")
@option(
    "--url",
    required=True,
    metavar="redis://HOST:PORT[/DB]",
    help="Redis server (redis://, rediss:// or unix:// URL)",
)
@option("--input-stream", required=True, metavar="S_IN", help="stream the vehicles write to")
@option("--output-stream", required=True, metavar="S_OUT", help="stream results go to")
@option(
    "--revision-stream",
    metavar="S_REV",
    help="where a model whose verdicts settle one fix late revises an earlier result "
    "(default: S_OUT:revisions)",
)
@option(
    "--warning-stream",
    metavar="S_WARN",
    help="where each vehicle's input warnings go, once each (a slow rate, repeated "
    "timestamps, implausible speeds; default: S_OUT:warnings)",
)
@option(
    "--group",
    required=True,
    metavar="G",
    help="consumer group (created, reading from the start, when missing)",
)
@option(
    "--consumer",
    required=True,
    metavar="NAME",
    help="this worker's name, unique among running workers",
)
@model_options
@option(
    "--batch-size",
    minimum=1,
    default=1000,
    help="messages per read, per transaction and per compiled detector call",
)
@option(
    "--lease-ms",
    minimum=100,
    default=10_000,
    help="a worker silent this long is taken for dead and its messages taken over",
)
@option(
    "--block-ms",
    minimum=1,
    default=1000,
    help="longest wait for new input when idle",
)
@option(
    "--exit-when-idle",
    "exit_when_idle_s",
    minimum=0.0,
    metavar="SECONDS",
    help="stop after this long without input (drain a backlog)",
)
def serve_redis(
    url: str,
    input_stream: str,
    output_stream: str,
    revision_stream: str | None,
    warning_stream: str | None,
    group: str,
    consumer: str,
    model_dir: Path | None,
    threshold: float | None,
    batch_size: int,
    lease_ms: int,
    block_ms: int,
    exit_when_idle_s: float | None,
) -> None:
    """Detect faults in live vehicle fixes from a Redis stream, one result per message."""
    import redis

    from .._run.fleet_redis import RedisStreamWorker, StepReport

    client = redis.Redis.from_url(url, decode_responses=True)
    try:
        client.ping()
    except redis.RedisError as exc:
        raise click.ClickException(f"cannot reach Redis at {url}: {exc}") from None
    worker = RedisStreamWorker(
        client,
        input_stream,
        output_stream,
        group,
        consumer,
        model=model_dir,
        threshold=threshold,
        batch_size=batch_size,
        lease_ms=lease_ms,
        revision_stream=revision_stream,
        warning_stream=warning_stream,
    )
    stop_requested = False

    def request_stop(signum: int, frame: FrameType | None) -> None:
        nonlocal stop_requested
        stop_requested = True

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    started = last_status = time.monotonic()
    processed = 0

    def status(report: StepReport) -> None:
        nonlocal processed, last_status
        processed += report.processed
        now = time.monotonic()
        if now - last_status >= _STATUS_EVERY_S:
            click.echo(
                f"{consumer}: {processed:,} messages processed, "
                f"{processed / (now - started):,.0f}/s",
                err=True,
            )
            last_status = now

    click.echo(
        f"{consumer}: serving {input_stream} -> {output_stream} (group {group}) on {url}", err=True
    )
    if worker.settles:
        click.echo(
            f"{consumer}: this model's verdicts settle one fix late: results are verdicts at "
            f"once, and {worker.revision_stream} revises those a vehicle's next fix changes",
            err=True,
        )
    click.echo(
        f"{consumer}: input warnings (once per vehicle and kind) go to {worker.warning_stream}",
        err=True,
    )
    total = worker.run(
        lambda: stop_requested, block_ms=block_ms, exit_when_idle_s=exit_when_idle_s, on_step=status
    )
    click.echo(f"{consumer}: stopped after {total:,} messages", err=True)
