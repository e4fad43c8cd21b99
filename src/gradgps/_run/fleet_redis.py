"""Live fleet detection on Redis Streams: a consumer-group worker with exactly-once effect.

Vehicles push fixes to one input stream (fields ``vehicle_id``, ``t``,
``lat``, ``lon``, optional ``speed``, ``heading``, the receiver's own
``fix_quality`` and ``satellites`` (a fix it reports as no fix is flagged,
never used) and other numeric channels). Any number of :class:`RedisStreamWorker` processes share one
consumer group on it; for every input message exactly one result message
lands on the output stream (``source_id`` = the input message id), in each
vehicle's order, even when workers are killed (SIGKILL) and restarted or
replaced. docs/fleet.md has the full argument; in short:

**Exactly-once effect.** A worker handles a page of its pending messages in
one ``WATCH``/``MULTI``/``EXEC`` transaction: it ``WATCH``-es the state keys
of the page's vehicles, reads them (each holds the detector state as JSON
and the id of the vehicle's last processed message), runs the detector, and
in one ``MULTI`` appends the results (``XADD``), stores the new states with
their last ids (``SET``) and acknowledges the inputs (``XACK``). A crash
before ``EXEC`` leaves everything as it was (the messages stay pending and
are redone); after ``EXEC`` all three happened. A message whose id is not
after its vehicle's stored last id was already processed by someone (a
worker that was wrongly thought dead): it is acknowledged without output.
If another worker changes one of the states in between, ``EXEC`` fails and
the page is redone from the stored states.

**Order per vehicle.** A consumer group hands messages to whichever
consumer asks first, so two workers could hold messages of one vehicle.
That is prevented by *ownership*: every vehicle has an owner consumer
(hash ``owner``), and the invariant is that all pending messages of a
vehicle sit in its owner's pending list. New messages are read by the Lua
script :data:`ROUTE_SCRIPT`, atomically with routing them: a message whose
vehicle is owned by another live consumer that still has pending messages
is moved to that owner (``XCLAIM``); otherwise the reader becomes the
vehicle's owner and keeps it (so vehicles move to idle workers, which
spreads the load). Each worker processes its own pending list in id order,
so each vehicle's messages are processed in stream order. Plain
``XAUTOCLAIM`` is not used for recovery because it picks entries by idle
time, regardless of vehicle, and would split a vehicle between consumers.

**Failure.** A worker refreshes ``alive:<consumer>`` (TTL ``lease_ms``)
while it runs. Restarted under the same consumer name it simply continues
with its pending list. A consumer whose key expired with messages still
pending is taken over by the next worker that runs the script: all its
pending messages and the vehicles they belong to move to that worker in one
atomic step, and it is deleted from the group. Consumer names must be
unique among running workers.

**Verdicts that settle one fix late** (a model with a confirm head, see
:attr:`gradgps.Detector.settled`). Each message still gets its one output at
once, its verdict at once. When a vehicle's next usable fix settles the
verdict of its last one and it differs from what the output said, a
*revision* goes to the stream :attr:`RedisStreamWorker.revision_stream`: the
same fields as an output, ``source_id`` naming the earlier message. The
vehicle's state record keeps the output of its fix still waiting
(``pending``), and the revision is written in the same transaction as the
output of the fix that settled it: exactly once too. Outputs with the
revisions applied (the later one wins) are the verdicts of batch detection;
a fix whose verdict nothing revised keeps the one of its output.

**Input warnings.** Each vehicle's fixes, usable or not, go through follow mode's input
checks (:class:`_Watch`: a look after :data:`CHECK_EVERY` fixes, then after
twice as many as the time before); each kind of warning goes once per vehicle to
:attr:`RedisStreamWorker.warning_stream` (``vehicle_id``, ``source_id``: the fix at
which it was found, ``warning``), in the transaction of that fix's output. The
checks' histograms live in the vehicle's state record (``checks``).

**Hostile messages and states.** Nothing a producer writes stops a worker.
Pages are read through :data:`READ_SCRIPT`, which hands every field over as
hex, so the worker sees the exact bytes whatever the client's decoding: a
message with a field name or value that is not UTF-8, or with a field
repeated (``vehicle_id`` twice), gets its own result, flagged with the
reason, and never reaches a detector. A message belongs to the vehicle of
its *first* ``vehicle_id`` field, as raw bytes, in the router and in the
worker alike (so ownership, ordering and deduplication agree). Fields other
than the position fields, ``fix_quality`` and ``satellites`` are ignored
(they are never passed on as keyword arguments). A stored state that cannot be restored (damaged JSON, another
model, a hand-edited array) is replaced by a fresh detector for that vehicle
and reported on the dead-letter stream ``<key_prefix>dead-letter``, in the
same transaction; so is a message whose processing raised, which also gets a
flagged result.
"""

from __future__ import annotations

import json
import math
import os
import re
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import KW_ONLY, astuple, dataclass, field, fields
from typing import TYPE_CHECKING, Any

from .._exceptions import ConfigError, GradGPSError
from .._result import RESULT_COLUMNS, PointResult
from .._tracks.input_checks import CHECK_EVERY, InputChecks, validated_rates

if TYPE_CHECKING:
    import redis
    from redis.commands.core import Script

    from .._grad.detector import FleetDetector, FleetResult

__all__ = ["OUTPUT_FIELDS", "READ_SCRIPT", "ROUTE_SCRIPT", "RedisStreamWorker", "StepReport"]

#: Fields of every output message, in order.
OUTPUT_FIELDS = ("source_id", "vehicle_id", "t", *RESULT_COLUMNS)

_MESSAGE_ID = re.compile(r"[0-9]{1,20}-[0-9]{1,20}")

#: Reads the caller's pending messages (``XREADGROUP ... 0``) and returns them as
#: ``{id, {hex(field name or value), ...}}``: the raw bytes whatever the client's decoding
#: (a non-UTF-8 byte must not make redis-py raise). A deleted entry has no fields.
READ_SCRIPT = """
local reply = redis.call('XREADGROUP', 'GROUP', ARGV[1], ARGV[2], 'COUNT', tonumber(ARGV[3]),
                         'STREAMS', KEYS[1], '0')
local entries = {}
if reply and type(reply[1]) == 'table' then
  entries = reply[1][2]
elseif reply and reply[2] then
  entries = reply[2]
end
local function hex(text)
  return (string.gsub(text, '.', function(c) return string.format('%02x', string.byte(c)) end))
end
local out = {}
for i, entry in ipairs(entries) do
  local fields = {}
  if entry[2] then
    for j, value in ipairs(entry[2]) do fields[j] = hex(value) end
  end
  out[i] = {entry[1], fields}
end
return out
"""

#: Reads new messages for the calling consumer and routes them to their
#: vehicles' owners, atomically (see the module docstring). Also takes over
#: consumers that died with pending messages. Returns {kept, passed on,
#: taken over, id of the stream's last entry or ''}.
ROUTE_SCRIPT = """
local stream, owners = KEYS[1], KEYS[2]
local group, me, count, alive_prefix = ARGV[1], ARGV[2], tonumber(ARGV[3]), ARGV[4]

-- Messages without a vehicle_id all belong to the pseudo-vehicle '' (so they
-- too are deduplicated by its state's last id).
local function vehicle_of(fields)
  if not fields then return '' end
  for i = 1, #fields, 2 do
    if fields[i] == 'vehicle_id' then return fields[i + 1] end
  end
  return ''
end

local function is_alive(name)
  return name == me or redis.call('EXISTS', alive_prefix .. name) == 1
end

local function has_pending(name)
  return #redis.call('XPENDING', stream, group, '-', '+', 1, name) > 0
end

-- Move every pending message of a dead consumer, and the vehicles they
-- belong to, to me; then delete the consumer.
local function take_over(dead)
  local moved = 0
  while true do
    local pending = redis.call('XPENDING', stream, group, '-', '+', 100, dead)
    if #pending == 0 then break end
    local ids = {}
    for i, p in ipairs(pending) do ids[i] = p[1] end
    local claimed = {}
    for _, entry in ipairs(redis.call('XCLAIM', stream, group, me, 0, unpack(ids))) do
      if entry and entry[2] then
        claimed[entry[1]] = true
        redis.call('HSET', owners, vehicle_of(entry[2]), me)
      end
    end
    for _, id in ipairs(ids) do
      -- deleted from the stream (trimmed): nothing left to process
      if not claimed[id] then redis.call('XACK', stream, group, id) end
    end
    moved = moved + #ids
  end
  redis.call('XGROUP', 'DELCONSUMER', stream, group, dead)
  return moved
end

local taken = 0
for _, consumer in ipairs(redis.call('XINFO', 'CONSUMERS', stream, group)) do
  local name, pending = nil, 0
  for i = 1, #consumer, 2 do
    if consumer[i] == 'name' then name = consumer[i + 1] end
    if consumer[i] == 'pending' then pending = tonumber(consumer[i + 1]) end
  end
  if name and pending > 0 and not is_alive(name) then taken = taken + take_over(name) end
end

local kept, passed = 0, 0
local reply = redis.call('XREADGROUP', 'GROUP', group, me, 'COUNT', count, 'STREAMS', stream, '>')
local entries = {}
if reply and type(reply[1]) == 'table' then
  entries = reply[1][2]  -- Redis: {{stream, entries}}
elseif reply and reply[2] then
  entries = reply[2]  -- fakeredis flattens a one-stream reply to {stream, entries}
end
do
  for _, entry in ipairs(entries) do
    local vehicle = vehicle_of(entry[2])
    local owner = redis.call('HGET', owners, vehicle)
    if owner and owner ~= me and is_alive(owner) and has_pending(owner) then
      redis.call('XCLAIM', stream, group, owner, 0, entry[1], 'JUSTID')
      passed = passed + 1
    else
      if owner and owner ~= me and not is_alive(owner) then taken = taken + take_over(owner) end
      redis.call('HSET', owners, vehicle, me)
      kept = kept + 1
    end
  end
end
local last = redis.call('XREVRANGE', stream, '+', '-', 'COUNT', 1)
return {kept, passed, taken, last[1] and last[1][1] or ''}
"""


class _BatchFailed(Exception):
    """Scoring a page in one batch raised; it is redone message by message."""


# A page whose states keep changing under it is redone at most this often
# (each conflict means another worker made progress on those vehicles).
_MAX_CONFLICTS = 100


@dataclass(frozen=True)
class StepReport:
    """What one :meth:`RedisStreamWorker.step` did."""

    routed_here: int
    routed_away: int
    taken_over: int
    processed: int
    skipped: int
    last_entry_id: str


@dataclass(frozen=True)
class _Message:
    id: str
    vehicle: bytes  # the first vehicle_id field's raw bytes; b'' when the message has none
    fields: Mapping[str, str]  # UTF-8 fields, first occurrence of each name
    problem: str = ""  # why the message cannot be used ('' when it can)


@dataclass
class _Watch:
    """A vehicle's input checks (:class:`~gradgps._tracks.input_checks.InputChecks`) as
    follow mode runs them: they look after :data:`CHECK_EVERY` fixes, then after
    twice as many as the time before, and say each kind of warning once."""

    checks: InputChecks
    said: list[str] = field(default_factory=list)
    since: int = 0  # fixes since the last look
    next_look: int = CHECK_EVERY

    def to_state(self) -> dict[str, Any]:
        return {
            "checks": self.checks.to_state(),
            "said": list(self.said),
            "since": self.since,
            "next_look": self.next_look,
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> _Watch:
        said = [str(kind) for kind in state["said"]]
        since, next_look = int(state["since"]), int(state["next_look"])
        if not 0 <= since < next_look:
            raise ValueError("'since' is not below 'next_look'")
        return cls(InputChecks.from_state(state["checks"]), said, since, next_look)

    def add(
        self, fixes: list[tuple[str, float, float, float, float, float]]
    ) -> list[tuple[int, str]]:
        """Take in fixes (source id, t, lat, lon, speed m/s, heading degrees; NaN:
        none), in order; returns each new warning with the index of the fix at which the
        checks found it."""
        found: list[tuple[int, str]] = []
        start = 0
        while start < len(fixes):
            end = min(len(fixes), start + self.next_look - self.since)
            self._feed(fixes[start:end])
            self.since += end - start
            if self.since == self.next_look:
                self.since, self.next_look = 0, 2 * self.next_look
                for kind, text in self.checks.findings():
                    if kind not in self.said:
                        self.said.append(kind)
                        found.append((end - 1, text))
            start = end
        return found

    def _feed(self, fixes: list[tuple[str, float, float, float, float, float]]) -> None:
        import numpy as np

        from .._tracks.track import canonical_heading

        t, lat, lon, speed, heading = np.array([f[1:] for f in fixes], dtype=np.float64).T
        self.checks.add_track("", t, lat, lon, speed, canonical_heading(heading))


@dataclass
class _Track:
    """What a vehicle's stored state says besides its detector: the id of the last message
    processed, the output of its fix whose verdict may still be revised (a model
    whose verdicts settle one fix late; ``None``: none), and its input checks."""

    last_id: str
    pending: dict[str, str] | None = None
    watch: _Watch | None = None  # None: no input checks (a page scored on its own)


def _decode_message(message_id: str, hex_fields: list[str]) -> _Message:
    """A message read by :data:`READ_SCRIPT`: its raw fields checked and decoded."""
    raw = [bytes.fromhex(x) for x in hex_fields]
    names, values = raw[0::2], raw[1::2]
    vehicle = b""
    fields: dict[str, str] = {}
    problems: list[str] = []
    seen: set[bytes] = set()
    for name, value in zip(names, values, strict=False):
        shown = name.decode("utf-8", "backslashreplace")
        if name == b"vehicle_id" and name not in seen:
            vehicle = value
        if name in seen:
            problems.append(f"field {shown!r} appears more than once")
            continue
        seen.add(name)
        try:
            fields[name.decode("utf-8")] = value.decode("utf-8")
        except UnicodeDecodeError:
            problems.append(f"field {shown!r} is not UTF-8 text")
    if len(names) != len(values):
        problems.append("message has a field name without a value")
    problem = ""
    if raw and problems:
        problem = "bad message: " + "; ".join(dict.fromkeys(problems))
    return _Message(message_id, vehicle, fields, problem)


def _id_key(message_id: str) -> tuple[int, int]:
    ms, _, seq = message_id.partition("-")
    return int(ms), int(seq or 0)


def _number(text: str | None) -> float:
    if text is None:
        return math.nan
    try:
        return float(text)
    except (ValueError, OverflowError):
        return math.nan


def _text(value: float) -> str:
    return repr(float(value))


def _output(message: _Message, verdict: Sequence[Any]) -> dict[str, str]:
    """The output message of ``message``; ``verdict``: a :class:`PointResult`'s fields in
    order (``anomaly``, ``score``, ... ``invalid_reason``)."""
    anomaly, score, bias, kind, lat, lon, alert, reason = verdict
    return {
        "source_id": message.id,
        "vehicle_id": message.vehicle.decode("utf-8", "backslashreplace"),
        "t": message.fields.get("t", ""),
        "anomaly": str(int(anomaly)),
        "score": _text(score),
        "bias_type": bias or "",
        "time_type": kind or "",
        "lat_clean": _text(lat),
        "lon_clean": _text(lon),
        "alert": str(int(alert)),
        "invalid_reason": reason,
    }


def _revision(pending: Mapping[str, str], verdict: Sequence[Any]) -> dict[str, str] | None:
    """The revision of the output ``pending`` to its settled ``verdict`` (fields of a
    :class:`PointResult` in order); ``None`` where the output already said it."""
    message = _Message(pending["source_id"], pending["vehicle_id"].encode(), pending)
    revised = _output(message, verdict)
    return None if revised == dict(pending) else revised


def _pending_output(value: Any) -> dict[str, str] | None:
    """The ``pending`` entry of a stored state record: an output message's fields."""
    if value is None:
        return None
    if (
        not isinstance(value, dict)
        or list(value) != list(OUTPUT_FIELDS)
        or not all(isinstance(v, str) for v in value.values())
        or not _MESSAGE_ID.fullmatch(value["source_id"])
    ):
        raise ValueError("'pending' is not an output message")
    return value


def _invalid(message: _Message, reason: str) -> dict[str, str]:
    """The output of a message that could not be used."""
    return _output(message, astuple(PointResult.invalid(reason)))


def _verdicts(result: FleetResult) -> list[tuple[Any, ...]]:
    """Each fix's :class:`PointResult` fields, in order, of a :class:`FleetResult`."""
    return list(zip(*(getattr(result, f.name).tolist() for f in fields(PointResult)), strict=True))


def _outputs(
    messages: list[_Message], result: FleetResult
) -> list[tuple[dict[str, str], tuple[Any, ...] | None]]:
    """:func:`_output` for a whole :meth:`FleetDetector.update_many` result at once, each
    with the verdict the fix settled (of its vehicle's fix before; ``None``: none)."""
    outputs = [_output(m, v) for m, v in zip(messages, _verdicts(result), strict=True)]
    if result.settled is None or result.has_settled is None:
        return [(o, None) for o in outputs]
    settled = _verdicts(result.settled)
    has = result.has_settled.tolist()
    return [(o, v if h else None) for o, v, h in zip(outputs, settled, has, strict=True)]


@dataclass(eq=False)
class RedisStreamWorker:
    """One consumer of a Redis Streams consumer group running GRAD per vehicle.

    ``client``: a ``redis.Redis`` made with ``decode_responses=True``.
    ``consumer`` must be unique among running workers (restart a killed one
    under the same name to continue its work at once). ``batch_size``:
    messages read and committed per transaction. ``lease_ms``: how long
    after its last sign of life a worker is taken for dead and its pending
    messages are taken over. ``cache_size``: vehicles whose detector states
    stay in memory (others are restored from their Redis state when needed).
    All vehicles' detectors live in one :class:`~gradgps.FleetDetector`, and
    each page's fixes are scored in one :meth:`~gradgps.FleetDetector.update_many`.
    Redis keys used: ``<key_prefix>owner``, ``<key_prefix>state:<vehicle>``,
    ``<key_prefix>alive:<consumer>``; the default prefix is
    ``gradgps:<input_stream>:<group>:``. ``revision_stream``: where the revisions of
    a model whose verdicts settle one fix late go (see the module docstring);
    default ``<output_stream>:revisions``. ``warning_stream``: where each vehicle's
    input warnings go, once each; default ``<output_stream>:warnings``.
    """

    client: redis.Redis
    input_stream: str
    output_stream: str
    group: str
    consumer: str
    _: KW_ONLY
    model: str | os.PathLike[str] | None = None
    threshold: float | None = None
    batch_size: int = 1000
    lease_ms: int = 10_000
    cache_size: int = 10_000
    key_prefix: str | None = None
    revision_stream: str | None = None
    warning_stream: str | None = None
    _fleet: FleetDetector = field(init=False, repr=False)
    _rates: tuple[float, float] = field(init=False, repr=False)
    _settles: bool = field(init=False, repr=False)
    # Vehicles whose state in self._fleet is current, with the id of the last message
    # it has seen (least recently used first).
    _tracks: OrderedDict[bytes, str] = field(init=False, repr=False)
    _route: Script = field(init=False, repr=False)
    _read: Script = field(init=False, repr=False)
    _dead: list[dict[str, str]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.key_prefix is None:
            self.key_prefix = f"gradgps:{self.input_stream}:{self.group}:"
        if self.revision_stream is None:
            self.revision_stream = f"{self.output_stream}:revisions"
        if self.warning_stream is None:
            self.warning_stream = f"{self.output_stream}:warnings"
        self._check()
        from .._grad.detector import FleetDetector

        self._fleet = FleetDetector(self.model, threshold=self.threshold)
        self._rates = validated_rates(self._fleet.model_.config)
        self._settles = self._fleet.model_.params.settles(self._fleet.model_.dims)
        self._tracks = OrderedDict()
        self._route = self.client.register_script(ROUTE_SCRIPT)
        self._read = self.client.register_script(READ_SCRIPT)
        self._dead = []

    def _check(self) -> None:
        kwargs = self.client.connection_pool.connection_kwargs
        if not kwargs.get("decode_responses"):
            raise ConfigError("the Redis client must be made with decode_responses=True")
        for name in ("input_stream", "output_stream", "group", "consumer"):
            if not getattr(self, name):
                raise ConfigError(f"{name} must not be empty")
        streams = (
            self.input_stream,
            self.output_stream,
            self.revision_stream,
            self.warning_stream,
        )
        if len(set(streams)) < len(streams):
            raise ConfigError("input, output, revision and warning streams must differ")
        if self.batch_size < 1 or self.lease_ms < 1 or self.cache_size < 1:
            raise ConfigError("batch_size, lease_ms and cache_size must be >= 1")

    # -- keys ----------------------------------------------------------------

    def _state_key(self, vehicle: bytes) -> bytes:
        return f"{self.key_prefix}state:".encode() + vehicle

    @property
    def settles(self) -> bool:
        """Whether the model's verdicts settle one fix late (revisions are written)."""
        return self._settles

    @property
    def dead_letter_stream(self) -> str:
        """Stream where unrestorable states and messages whose processing failed are reported."""
        return f"{self.key_prefix}dead-letter"

    def _alive_key(self, consumer: str) -> str:
        return f"{self.key_prefix}alive:{consumer}"

    # -- the loop -------------------------------------------------------------

    def ensure_group(self) -> None:
        """Create the consumer group (and the input stream) when missing, reading from the start."""
        import redis

        try:
            self.client.xgroup_create(self.input_stream, self.group, id="0", mkstream=True)
        except redis.ResponseError as exc:
            if "BUSYGROUP" not in str(exc):
                raise

    def heartbeat(self) -> None:
        """Tell the other workers this consumer is alive for the next ``lease_ms``."""
        self.client.set(self._alive_key(self.consumer), "1", px=self.lease_ms)

    def route(self) -> tuple[int, int, int, str]:
        """Read one batch of new messages and route them (:data:`ROUTE_SCRIPT`).

        Returns (kept here, passed to their owners, taken over from dead
        consumers, id of the stream's last entry or '').
        """
        kept, passed, taken, last = self._route(
            keys=[self.input_stream, f"{self.key_prefix}owner"],
            args=[self.group, self.consumer, self.batch_size, f"{self.key_prefix}alive:"],
        )
        return int(kept), int(passed), int(taken), str(last)

    def process_pending(self) -> tuple[int, int]:
        """Process this consumer's pending messages, page by page in id order, until none is left.

        Returns (results written, messages skipped as already processed).
        """
        processed = skipped = 0
        while True:
            entries: Any = self._read(
                keys=[self.input_stream], args=[self.group, self.consumer, self.batch_size]
            )
            if not entries:
                return processed, skipped
            done, dropped = self._commit([_decode_message(str(i), list(f)) for i, f in entries])
            processed += done
            skipped += dropped
            self.heartbeat()

    def step(self) -> StepReport:
        """Heartbeat, route one batch of new messages, then process the whole pending list."""
        self.heartbeat()
        kept, passed, taken, last = self.route()
        processed, skipped = self.process_pending()
        return StepReport(
            routed_here=kept,
            routed_away=passed,
            taken_over=taken,
            processed=processed,
            skipped=skipped,
            last_entry_id=last,
        )

    def run(
        self,
        should_stop: Callable[[], bool],
        *,
        block_ms: int = 1000,
        exit_when_idle_s: float | None = None,
        on_step: Callable[[StepReport], None] | None = None,
    ) -> int:
        """Run steps until ``should_stop()``; returns the number of messages processed.

        When there is nothing to do it waits up to ``block_ms`` for a new
        input message (a blocking read that consumes nothing).
        ``exit_when_idle_s`` stops the loop after that long without work
        (draining a backlog). On a clean stop the alive key is deleted so
        this consumer's vehicles move to other workers at once.
        """
        self.ensure_group()
        total = 0
        idle_since = time.monotonic()
        try:
            while not should_stop():
                report = self.step()
                total += report.processed
                if on_step is not None:
                    on_step(report)
                if (
                    report.processed
                    or report.routed_here
                    or report.routed_away
                    or report.taken_over
                ):
                    idle_since = time.monotonic()
                    continue
                if (
                    exit_when_idle_s is not None
                    and time.monotonic() - idle_since >= exit_when_idle_s
                ):
                    break
                self.client.xread(
                    {self.input_stream: report.last_entry_id or "0-0"}, count=1, block=block_ms
                )
        finally:
            self.client.delete(self._alive_key(self.consumer))
        return total

    # -- one page --------------------------------------------------------------

    def _restore(self, vehicle: bytes, stored: bytes | str | None) -> _Track:
        """Make the vehicle's detector in the fleet the one of its stored state (the cached one
        when that is current); returns the id of the last message that state has seen and
        the output of its fix whose verdict may still be revised.

        ``stored``: the state key's raw bytes (``None`` when the key does not exist).

        A stored state that cannot be restored gives a fresh detector (and keeps its last
        message id when that is readable), reported on the dead-letter stream.
        """
        last_id, saved, problem, pending = "0-0", None, "", None
        watch = None
        if stored is not None:
            try:
                record = json.loads(stored)
                saved = record["detector"]
                last_id = str(record["last_id"])
                if not _MESSAGE_ID.fullmatch(last_id):
                    last_id = "0-0"
                    raise ValueError("'last_id' is not a stream message id")
                pending = _pending_output(record.get("pending"))
                if record.get("checks") is not None:
                    watch = _Watch.from_state(record["checks"])
            except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as exc:
                problem = f"stored state is not readable ({type(exc).__name__}: {exc})"
                saved = pending = watch = None
        if watch is None:
            watch = _Watch(InputChecks(*self._rates))
        if not problem and self._tracks.get(vehicle) == last_id:
            self._tracks.move_to_end(vehicle)
            return _Track(last_id, pending, watch)
        self._forget([vehicle])
        if saved is not None:
            try:
                self._fleet.set_state(vehicle, saved)
            except GradGPSError as exc:
                problem = f"stored detector state refused ({exc})"
                self._fleet.drop(vehicle)
        if problem:
            self._dead.append(
                {
                    "key": self._state_key(vehicle).decode("utf-8", "backslashreplace"),
                    "problem": problem[:2000] + ": the vehicle restarts with a fresh detector",
                }
            )
        return _Track(last_id, pending, watch)

    def _forget(self, vehicles: Any) -> None:
        """Drop these vehicles' in-memory states: the stored ones are read again when needed."""
        for vehicle in vehicles:
            self._tracks.pop(vehicle, None)
            self._fleet.drop(vehicle)

    def _commit(self, messages: list[_Message]) -> tuple[int, int]:
        """Process one page of pending messages in one transaction; returns (processed, skipped)."""
        import redis
        from redis.client import NEVER_DECODE

        vehicles = sorted({m.vehicle for m in messages})
        keys = [self._state_key(v) for v in vehicles]
        per_message = False  # score the page message by message (after a failed batch)
        for _ in range(_MAX_CONFLICTS):
            with self.client.pipeline(transaction=True) as pipe:
                try:
                    self._dead = []
                    if keys:
                        pipe.watch(*keys)  # type: ignore[no-untyped-call]
                    # Raw bytes: a state key holding non-UTF-8 bytes (hand-written, damaged)
                    # must not make the client raise for the whole page, on every restart.
                    stored: list[Any] = (
                        pipe.execute_command(  # type: ignore[no-untyped-call]
                            "MGET", *keys, **{NEVER_DECODE: []}
                        )
                        if keys
                        else []
                    )
                    tracks = {v: self._restore(v, s) for v, s in zip(vehicles, stored, strict=True)}
                    outputs, revisions, changed = self._run_detectors(messages, tracks, per_message)
                    warnings = self._look(messages, outputs, tracks)
                    pipe.multi()
                    for fields in outputs:
                        pipe.xadd(self.output_stream, fields)  # type: ignore[arg-type]
                    for fields in revisions:
                        pipe.xadd(self.revision_stream, fields)  # type: ignore[arg-type]
                    for fields in warnings:
                        pipe.xadd(self.warning_stream, fields)  # type: ignore[arg-type]
                    for entry in self._dead:
                        pipe.xadd(self.dead_letter_stream, entry)  # type: ignore[arg-type]
                    for vehicle in changed:
                        record: dict[str, Any] = {
                            "last_id": tracks[vehicle].last_id,
                            "detector": self._fleet.get_state(vehicle),
                        }
                        if tracks[vehicle].pending is not None:
                            record["pending"] = tracks[vehicle].pending
                        watch = tracks[vehicle].watch
                        if watch is not None:
                            record["checks"] = watch.to_state()
                        pipe.set(self._state_key(vehicle), json.dumps(record))
                    pipe.xack(self.input_stream, self.group, *[m.id for m in messages])
                    pipe.execute()
                except redis.WatchError:
                    # Someone else moved these vehicles on: our in-memory detectors may have
                    # run ahead of the stored states, so forget them and redo the page.
                    self._forget(vehicles)
                    continue
                except _BatchFailed:
                    # Scoring the page at once raised (a bug): redo it message by message
                    # from the stored states, so only the failing message is lost.
                    self._forget(vehicles)
                    per_message = True
                    continue
                except BaseException:
                    # Dying mid-page (or a Redis error): the in-memory states may have run
                    # ahead of the stored ones, which are what the page is redone from.
                    self._forget(vehicles)
                    raise
            for vehicle, track in tracks.items():
                self._tracks[vehicle] = track.last_id
                self._tracks.move_to_end(vehicle)
            while len(self._tracks) > self.cache_size:
                vehicle, _ = self._tracks.popitem(last=False)
                self._fleet.drop(vehicle)
            return len(outputs), len(messages) - len(outputs)
        raise RuntimeError(
            f"{len(messages)} messages starting at {messages[0].id}: their vehicles' "
            f"states changed under {_MAX_CONFLICTS} transactions in a row"
        )

    def _look(
        self,
        messages: list[_Message],
        outputs: list[dict[str, str]],
        tracks: dict[bytes, _Track],
    ) -> list[dict[str, str]]:
        """The page's fixes, usable or not, through their vehicles' input checks (as batch
        and follow mode give them every fix read: a repeated or backward time is what some
        of them are there to see); returns the
        warning messages to write (``vehicle_id``, ``source_id``: the fix at which the
        checks found it, ``warning``)."""
        read: dict[bytes, list[tuple[str, float, float, float, float, float]]] = {}
        by_id = {o["source_id"]: o for o in outputs}
        for message in messages:
            output = by_id.get(message.id)
            if output is None:
                continue
            f = message.fields
            read.setdefault(message.vehicle, []).append(
                (
                    message.id,
                    _number(f.get("t")),
                    _number(f.get("lat")),
                    _number(f.get("lon")),
                    _number(f.get("speed")),
                    _number(f.get("heading")),
                )
            )
        warnings: list[dict[str, str]] = []
        for vehicle, fixes in read.items():
            watch = tracks[vehicle].watch
            if watch is None:
                continue
            for at, text in watch.add(fixes):
                warnings.append(
                    {
                        "vehicle_id": vehicle.decode("utf-8", "backslashreplace"),
                        "source_id": fixes[at][0],
                        "warning": text,
                    }
                )
        return warnings

    def _run_detectors(
        self,
        messages: list[_Message],
        tracks: dict[bytes, _Track],
        per_message: bool = False,
    ) -> tuple[list[dict[str, str]], list[dict[str, str]], set[bytes]]:
        """The page's outputs in message order, its revisions, and the vehicles whose state
        changed.

        ``tracks``: each vehicle's last processed message id and output still waiting to
        be settled, moved on here. The page's usable messages are scored in one
        :meth:`FleetDetector.update_many` (one call per message with ``per_message``, see
        :meth:`_score`).
        """
        outputs: list[dict[str, str] | None] = []
        changed: set[bytes] = set()
        fixes: list[_Message] = []
        at: list[int] = []  # where each of ``fixes`` goes in ``outputs``
        for message in messages:
            track = tracks[message.vehicle]
            if _id_key(message.id) <= _id_key(track.last_id):
                continue  # already in the output stream: processed before a takeover
            if message.problem:
                output: dict[str, str] | None = _invalid(message, message.problem)
            elif not message.fields:
                output = _invalid(
                    message, "message deleted from the stream before it was processed"
                )
            elif not message.vehicle:
                output = _invalid(message, "message has no vehicle_id")
            else:
                output = None
                fixes.append(message)
                at.append(len(outputs))
            outputs.append(output)
            track.last_id = message.id
            changed.add(message.vehicle)
        revisions: list[dict[str, str]] = []
        if fixes:
            scored = self._score(fixes, per_message)
            for k, message, (output, settled) in zip(at, fixes, scored, strict=True):
                outputs[k] = output
                if not self._settles:
                    continue
                # The vehicle's fix still waiting is settled by this one, or final as it is
                # when this one began a new segment; an unusable fix leaves it waiting.
                track = tracks[message.vehicle]
                if settled is not None and track.pending is not None:
                    revised = _revision(track.pending, settled)
                    if revised is not None:
                        revisions.append(revised)
                if output["invalid_reason"] == "":
                    track.pending = output
        return [o for o in outputs if o is not None], revisions, changed

    def _score(
        self, fixes: list[_Message], per_message: bool
    ) -> list[tuple[dict[str, str], tuple[Any, ...] | None]]:
        """The outputs of these messages (in order), each with the verdict it settled
        (:func:`_outputs`), scored in one batch; if that raises (a
        bug must not stop the fleet), :class:`_BatchFailed`, and the page is redone with
        ``per_message``: message by message, a failing one reported and its vehicle
        restarted with a fresh detector."""

        def batch(messages: list[_Message]) -> FleetResult:
            # Other fields (sensor channels) are not used by the position model.
            given = [m.fields for m in messages]
            return self._fleet.update_many(
                [m.vehicle for m in messages],
                [_number(f.get("t")) for f in given],
                [_number(f.get("lat")) for f in given],
                [_number(f.get("lon")) for f in given],
                [_number(f.get("speed")) for f in given],
                [_number(f.get("heading")) for f in given],
                fix_quality=[f.get("fix_quality") for f in given],
                satellites=[_number(f.get("satellites")) for f in given],
            )

        if not per_message:
            try:
                return _outputs(fixes, batch(fixes))
            except Exception as exc:
                # The states may be part way through the page: redo it from the stored
                # states, message by message (see _commit).
                raise _BatchFailed from exc
        outputs = []
        for message in fixes:
            try:
                outputs.extend(_outputs([message], batch([message])))
            except Exception as exc:  # report it, go on
                text = f"{type(exc).__name__}: {exc}"[:2000]
                self._fleet.drop(message.vehicle)
                self._dead.append({"source_id": message.id, "problem": text})
                outputs.append((_invalid(message, f"could not be processed ({text})"), None))
        return outputs


def parse_output(fields: Mapping[str, str]) -> dict[str, Any]:
    """An output message's fields as Python values (numbers as numbers), for consumers and tests."""
    ints = {"anomaly", "alert"}
    floats = {"score", "lat_clean", "lon_clean", "t"}
    return {k: int(v) if k in ints else _number(v) if k in floats else v for k, v in fields.items()}
