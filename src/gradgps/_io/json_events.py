"""A JSON file as a stream of parse events, read in bounded memory (ijson's C parser).

The GeoJSON reader (:mod:`gradgps._io.geojson_rows`) reads documents of any size
this way: the values it needs are built from the events, at most a budget of them
at a time, and everything else is skipped as it streams past. Several cursors may
read one file at once, each with a handle of its own (a ``.gz`` file is
decompressed by each), so that values far apart in the file (a LineString's
vertices and its ``coordTimes``) can be paired without holding either.

Numbers are the ``int`` and ``float`` :func:`json.loads` gives (``use_float``:
``float(text)``, never ``Decimal``). The parser holds to RFC 8259 where
:func:`json.loads` is lenient: ``NaN``, ``Infinity``, a number beyond the float
range (``1e400``), an integer beyond 64 bits, invalid UTF-8 and data after the
document are errors. A UTF-8
byte order mark before the document is skipped.
"""

from __future__ import annotations

import io
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import ijson
import numpy as np

from .._exceptions import InputError
from .files import READ_ERRORS, open_bytes

__all__ = ["Budget", "Event", "JsonCursor", "Unbuilt"]

#: One parse event: ``(kind, value)``, kind one of ijson's ``start_map``, ``map_key``,
#: ``end_map``, ``start_array``, ``end_array``, ``null``, ``boolean``, ``number``, ``string``.
Event = tuple[str, Any]

_DEPTH: Final = {"start_map": 1, "start_array": 1, "end_map": -1, "end_array": -1}
_OPEN: Final = frozenset(("start_map", "start_array"))
_BOM: Final = b"\xef\xbb\xbf"


@dataclass
class Budget:
    """How many more events may be built into values (shared by the values of one unit,
    a GeoJSON feature): a container that would need more is not built, and
    ``overdrawn`` says one was not."""

    left: int
    overdrawn: bool = False


@dataclass(frozen=True)
class Unbuilt:
    """A container left unbuilt because the budget ran out; ``kind`` is its first event
    (``start_map`` or ``start_array``). Whoever needs it reads it again with a cursor of
    its own."""

    kind: str


class _NoBom:
    """``raw`` without a leading UTF-8 byte order mark (as ``utf-8-sig`` decodes): the
    one method the parser calls, ``read``."""

    def __init__(self, raw: io.BufferedIOBase) -> None:
        self._raw = raw
        head = raw.read(len(_BOM))
        self._head = b"" if head == _BOM else head

    def read(self, size: int | None = -1) -> bytes:
        head, self._head = self._head, b""
        if size is None or size < 0:
            return head + self._raw.read()
        if len(head) >= size:
            self._head = head[size:]
            return head[:size]
        return head + self._raw.read(size - len(head))


#: Longest string (its bytes between the quotes) or other scalar (a number, a literal)
#: the parser may meet: it holds a token whole until it ends, so a gigabyte-long string
#: would be held whole (issue 18). As long as a CSV line (``MAX_LINE_BYTES``) or a GPX
#: text may be; no track's name, time or property needs more.
MAX_SCALAR_BYTES: Final = 1 << 20
#: The bytes that end a scalar outside strings: JSON's structure and whitespace.
_SEPARATORS: Final = np.frombuffer(b'{}[],: \t\r\n"', dtype=np.uint8)


class _ScalarBound:
    """``raw`` (anything with ``read``) that refuses, as it is read, a string or other
    scalar longer than :data:`MAX_SCALAR_BYTES`, before the parser has buffered it.

    A tokenizer's state carried across reads, vectorised per block: where strings are
    (a quote not escaped by an odd run of backslashes opens or closes one), and the
    length of the run of token bytes (string contents, or non-separator bytes outside
    strings) that each block ends with. Invalid JSON is the parser's to report; this only
    bounds what it would hold.
    """

    def __init__(self, raw: Any, source: str, limit: int = MAX_SCALAR_BYTES) -> None:
        self._raw = raw
        self._source = source
        self._limit = limit
        self._in_string = False
        self._run = 0  # token bytes the last block ended with
        self._backslashes = 0  # backslashes the last block ended with

    def read(self, size: int | None = -1) -> bytes:
        block = self._raw.read(size)
        if block:
            self._scan(np.frombuffer(block, dtype=np.uint8))
        return bytes(block)

    def _scan(self, b: np.ndarray) -> None:
        n = len(b)
        index = np.arange(n)
        backslash = b == ord("\\")
        # Backslashes right before each byte (the run carried over from the last block).
        last_other = np.maximum.accumulate(np.where(backslash, -1, index))
        before = np.empty(n, dtype=np.int64)
        before[0] = self._backslashes
        runs = index[1:] - 1 - last_other[:-1]
        before[1:] = np.where(last_other[:-1] < 0, runs + self._backslashes, runs)
        quote = (b == ord('"')) & (before % 2 == 0)
        flips = np.cumsum(quote)
        # Inside a string at a byte: the state carried in, flipped by every quote up to it.
        inside = (flips % 2 == 1) ^ self._in_string
        inside[quote] = False
        scalar = ~inside & ~np.isin(b, _SEPARATORS)
        token = inside | scalar
        last_break = np.maximum.accumulate(np.where(token, -1, index))
        length = index - last_break
        length[last_break < 0] += self._run
        if int(length.max(initial=0)) > self._limit:
            raise InputError(
                f"a string or number longer than {self._limit:,} bytes",
                source=self._source,
                hint="no track's name, time or property needs one: is this the right file?",
            )
        self._run = int(length[-1]) if token[-1] else 0
        trailing = n - 1 - int(last_other[-1])
        self._backslashes = trailing + (self._backslashes if last_other[-1] < 0 else 0)
        self._in_string ^= bool(int(flips[-1]) % 2)


def longest_scalar(data: bytes) -> int:
    """The readable reference of :class:`_ScalarBound`: the longest run of string contents
    (between an opening quote and the next quote not escaped) or of non-separator bytes
    outside strings in ``data``, one byte at a time (tests check they agree)."""
    longest = run = 0
    in_string = escaped = False
    for byte in data:
        if in_string:
            if escaped:
                escaped, run = False, run + 1
            elif byte == ord("\\"):
                escaped, run = True, run + 1
            elif byte == ord('"'):
                in_string, run = False, 0
            else:
                run += 1
        elif byte == ord('"'):
            in_string, run = True, 0
        elif byte in _SEPARATORS:
            run = 0
        else:
            run += 1
        longest = max(longest, run)
    return longest


class JsonCursor:
    """The parse events of one JSON file, read forward once, with the current nesting
    ``depth`` (0 outside the document, 1 inside the top-level container...).

    Every problem is an :class:`InputError` naming the file: invalid JSON (with
    ``where``, set by the caller, e.g. ``"feature 12"``, and the text near the
    error), or a file that cannot be read. Close it (or use it in ``with``).
    """

    def __init__(self, path: Path, source: str) -> None:
        self.source = source
        self.where = ""
        self.depth = 0
        #: Set when an object built had a key twice at its top level (cleared by the caller).
        self.repeated = False
        self._pending: list[Event] = []
        self._files = ExitStack()
        raw = self._files.enter_context(open_bytes(path))
        try:
            self._events = ijson.basic_parse(_ScalarBound(_NoBom(raw), source), use_float=True)
        except READ_ERRORS as exc:
            self._files.close()
            raise InputError(f"cannot read: {exc}", source=source) from None

    def __enter__(self) -> JsonCursor:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self._files.close()

    def next(self) -> Event:
        """The next event (the document's end is an error: the caller knows where it is)."""
        if self._pending:
            event = self._pending.pop()
        else:
            try:
                event = next(self._events)
            except StopIteration:
                raise self._invalid("the document ends early") from None
            except ijson.JSONError as exc:
                raise self._invalid(_parser_message(exc)) from None
            except READ_ERRORS as exc:
                raise InputError(f"cannot read: {exc}", source=self.source) from None
        self.depth += _DEPTH.get(event[0], 0)
        return event

    def push_back(self, event: Event) -> None:
        """Make ``event`` (just read) the next one again."""
        self._pending.append(event)
        self.depth -= _DEPTH.get(event[0], 0)

    def skip_to(self, depth: int) -> None:
        """Read on until the nesting depth is ``depth`` (out of the containers opened since)."""
        while self._pending and self.depth > depth:
            self.next()
        level = self.depth
        if level <= depth:
            return
        try:
            for kind, _ in self._events:
                level += _DEPTH.get(kind, 0)
                if level == depth:
                    break
            else:
                raise self._invalid("the document ends early")
        except ijson.JSONError as exc:
            raise self._invalid(_parser_message(exc)) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=self.source) from None
        self.depth = level

    def skip(self, first: Event) -> None:
        """Skip the rest of the value whose first event was ``first``."""
        if first[0] in _OPEN:
            self.skip_to(self.depth - 1)

    def build(self, first: Event, budget: Budget | None = None) -> Any:
        """The value whose first event was ``first``, as :func:`json.loads` builds it
        (a key given twice keeps its first place and its last value). A scalar is always
        built; a container costs one unit of ``budget`` per event, and one that would
        overdraw it is skipped and returned as :class:`Unbuilt`."""
        kind, value = first
        if kind not in _OPEN:
            return value
        return self._container(kind, budget)

    def members(self, budget: Budget | None = None) -> list[tuple[str, Any]]:
        """The members of the object whose ``start_map`` was just read, in file order, a
        key given twice as often as it is given; each value as :meth:`build` builds it.
        (One loop over the parser's events: this is what reads most of a file.)"""
        out: list[tuple[str, Any]] = []
        key = ""
        events = self._events
        self._no_pending()
        try:
            for kind, value in events:
                if kind == "map_key":
                    key = value
                elif kind == "end_map":
                    self.depth -= 1
                    return out
                elif kind == "start_map" or kind == "start_array":
                    self.depth += 1
                    out.append((key, self._container(kind, budget)))
                else:
                    out.append((key, value))
        except ijson.JSONError as exc:
            raise self._invalid(_parser_message(exc)) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=self.source) from None
        raise self._invalid("the document ends early")

    def _container(self, first: str, budget: Budget | None) -> Any:
        """A container whose first event, ``first``, was just read (see :meth:`build`)."""
        base = self.depth - 1
        # Events still allowed: for no budget, -1 and below (never back to -1 when counted).
        left = budget.left if budget is not None else -1
        if budget is not None and left <= 0:
            self.skip_to(base)
            budget.overdrawn = True
            return Unbuilt(first)
        self._no_pending()
        root: Any = {} if first == "start_map" else []
        parent = root
        in_list = first == "start_array"
        key: Any = None
        stack: list[tuple[Any, bool, Any]] = []
        try:
            for kind, value in self._events:
                left -= 1
                if left == -1:
                    self.depth = base + 1 + len(stack) + _DEPTH.get(kind, 0)
                    self.skip_to(base)
                    if budget is not None:
                        budget.left = 0
                        budget.overdrawn = True
                    return Unbuilt(first)
                if kind == "map_key":
                    if not stack and value in parent:
                        self.repeated = True
                    key = value
                    continue
                if kind == "end_map" or kind == "end_array":
                    if not stack:
                        self.depth = base
                        if budget is not None:
                            budget.left = left
                        return root
                    parent, in_list, key = stack.pop()
                    continue
                if kind == "start_map" or kind == "start_array":
                    child: Any = {} if kind == "start_map" else []
                    if in_list:
                        parent.append(child)
                    else:
                        parent[key] = child
                    stack.append((parent, in_list, key))
                    parent, in_list, key = child, kind == "start_array", None
                elif in_list:
                    parent.append(value)
                else:
                    parent[key] = value
        except ijson.JSONError as exc:
            raise self._invalid(_parser_message(exc)) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=self.source) from None
        raise self._invalid("the document ends early")

    def _no_pending(self) -> None:
        # The fast loops read the parser directly: nothing may be pushed back before them.
        if self._pending:
            raise AssertionError("an event pushed back before a value is built")

    def finish(self) -> None:
        """Check that nothing but whitespace follows the document."""
        try:
            for _ in self._events:
                raise self._invalid("data after the document")
        except ijson.JSONError as exc:
            raise self._invalid(_parser_message(exc)) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=self.source) from None

    def _invalid(self, message: str) -> InputError:
        where = f" (in {self.where})" if self.where else ""
        return InputError(
            f"not valid GeoJSON{where}: {message}",
            source=self.source,
            hint="the file is cut off or not JSON; repair it or pass the right format",
        )


def _parser_message(exc: Exception) -> str:
    """yajl's message on one line: its first line and the text near the error."""
    text = exc.args[0] if exc.args else str(exc)
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    if not lines:
        return "invalid JSON"
    near = lines[1] if len(lines) > 2 else ""
    return f"{lines[0]} near {near!r}" if near else lines[0]
