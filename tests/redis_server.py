"""A throwaway ``redis-server`` on 127.0.0.1 for integration tests.

Started on a free port with its own temporary directory, no persistence and
loopback only; stopped (and waited for) afterwards. When the binary is
missing the test skips, unless ``GRADGPS_REQUIRE_REDIS=1`` (CI sets it, after
installing the Debian package) makes that a failure.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

_START_TIMEOUT_S = 10.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def require_redis_server() -> str:
    """The path of redis-server, or skip/fail the test (see the module docstring)."""
    path = shutil.which("redis-server")
    if path is None:
        msg = (
            "redis-server not found (Debian package redis-server: apt-get install -y redis-server)"
        )
        if os.environ.get("GRADGPS_REQUIRE_REDIS") == "1":
            pytest.fail(msg + "; GRADGPS_REQUIRE_REDIS=1 forbids skipping")
        pytest.skip(msg)
    return path


@contextmanager
def redis_server(workdir: Path) -> Iterator[str]:
    """Run a redis-server for the duration of the block; yields its ``redis://`` URL."""
    import redis

    binary = require_redis_server()
    for _ in range(5):  # another process may grab the free port first
        port = _free_port()
        proc = subprocess.Popen(
            [
                binary,
                "--bind",
                "127.0.0.1",
                "--port",
                str(port),
                "--dir",
                str(workdir),
                "--save",
                "",
                "--appendonly",
                "no",
                "--protected-mode",
                "yes",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        url = f"redis://127.0.0.1:{port}/0"
        client = redis.Redis.from_url(url, socket_timeout=1.0)
        deadline = time.monotonic() + _START_TIMEOUT_S
        try:
            while proc.poll() is None and time.monotonic() < deadline:
                try:
                    client.ping()
                    break
                except redis.ConnectionError:
                    time.sleep(0.05)
            else:
                continue  # exited (port taken) or never answered: try another port
            yield url
            return
        finally:
            client.close()
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    pytest.fail("could not start redis-server on a free port of 127.0.0.1")
