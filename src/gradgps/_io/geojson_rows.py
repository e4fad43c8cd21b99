"""The rows of a GeoJSON file, one fix at a time, in bounded memory however big the file.

What the rows are (the module docstring of :mod:`gradgps._io.geojson` says why):
every Point feature is one row, its properties (but ``lat``, ``lon``, ``alt``) and
then ``lon``, ``lat`` and, given a third coordinate, ``alt``; every vertex of a
LineString or MultiLineString is a row ``track`` (the feature's ``name`` property,
else its index among the features), ``lon``, ``lat`` (, ``alt``), ``time`` (the
vertex's entry in the first of :data:`TIME_ARRAYS` that is an array, the parts of a
MultiLineString's array of arrays one after another; ``None`` past its end). A
property value that is an array or an object is kept as its JSON text (as
:func:`json.dumps` writes it), and so is such a time. Other geometries give no row.

How the file is read: the main cursor (:class:`~gradgps._io.json_events.JsonCursor`)
reads each feature whole, every value it needs built in memory, as long as the
feature's containers hold at most :data:`FEATURE_EVENTS` parse events. Beyond that
a container is left unbuilt (a track as one LineString of a million vertices, its
``coordTimes``) and streamed when the feature's rows are made, by cursors of their
own on the same file, each going forward once through it: one for coordinates,
one for times, one for big property values. So vertex ``i`` is paired with time
``i`` with neither array in memory, whatever the order of the keys (a Feature's
``geometry`` before its ``properties``, or ``coordinates`` before ``type``, as a
writer that sorts keys puts them).

What makes a file unusable is an :class:`~gradgps.InputError`, met in file order:
invalid JSON; not a FeatureCollection or Feature; ``features``, a feature, its
``geometry`` or ``properties`` of the wrong JSON type; a key that decides the
reading (``type``, ``features``, ``geometry``, ``properties``, ``coordinates``)
twice in one object; coordinates that are not positions (an array of at least two
values, the first three neither arrays nor objects); no Point or LineString rows.
"""

from __future__ import annotations

import json
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from .._exceptions import InputError
from .json_events import Budget, Event, JsonCursor, Unbuilt

__all__ = ["FEATURE_EVENTS", "TIME_ARRAYS", "FeatureRows"]

#: Per-vertex time arrays, by precedence (togeojson writes ``coordTimes`` from GPX).
TIME_ARRAYS: Final = ("coordTimes", "coordinateTimes", "times", "timestamps", "time")
#: Parse events of one feature built in memory; a container beyond them is streamed.
FEATURE_EVENTS = 1 << 16

_LINES: Final = ("LineString", "MultiLineString")
_COLLECTION: Final = "FeatureCollection"
_FEATURE: Final = "Feature"
_SKIPPED: Final = ("lat", "lon", "alt")
_NESTED: Final = (dict, list)  # a value kept as its JSON text
_HINT: Final = "a track as Point features with a time property, or LineStrings"


@dataclass(frozen=True)
class _Far:
    """A property value too big to build with its feature: the ``occurrence``-th
    (1-based) value of ``key`` in the feature's properties, a container of ``kind``."""

    key: str
    occurrence: int
    kind: str


@dataclass
class _Scanned:
    """One feature as the main cursor read it: big containers left :class:`Unbuilt`
    (coordinates) or :class:`_Far` (properties)."""

    index: int
    geometry_type: Any = None
    coordinates: Any = None
    properties: dict[str, Any] = field(default_factory=dict)


class FeatureRows:
    """The rows of the GeoJSON file ``path``, each a dict (column -> value), in file order.

    Iterate it once. ``doc_type``: the document's ``type`` when already known (a second
    pass over the file; after a pass, :attr:`doc_type` holds it), else it is found.
    """

    def __init__(self, path: Path, doc_type: str | None = None) -> None:
        self.path = path
        self.source = str(path)
        self.doc_type = doc_type

    def __iter__(self) -> Iterator[dict[str, Any]]:
        reader = _Reader(self.path, self.source, self.doc_type)
        try:
            yield from reader.rows()
        finally:
            reader.close()
        self.doc_type = reader.doc_type


class _Reader:
    """One pass over a file: the main cursor and, opened when first needed, the cursors
    streaming big coordinates, times and property values."""

    def __init__(self, path: Path, source: str, doc_type: str | None) -> None:
        self.path = path
        self.source = source
        self.doc_type: Any = doc_type
        self.main = JsonCursor(path, source)
        self._far: dict[str, _Navigator] = {}

    def close(self) -> None:
        self.main.close()
        for navigator in self._far.values():
            navigator.cursor.close()

    def error(self, message: str, hint: str | None = None) -> InputError:
        return InputError(message, source=self.source, hint=hint)

    def navigator(self, role: str) -> _Navigator:
        if role not in self._far:
            self._far[role] = _Navigator(JsonCursor(self.path, self.source), self.doc_type)
        return self._far[role]

    # --- the document ---------------------------------------------------------------

    def rows(self) -> Iterator[dict[str, Any]]:
        cur = self.main
        first = cur.next()
        if first[0] != "start_map":
            cur.skip(first)
            cur.finish()
            raise self._not_a_collection()
        seen: set[str] = set()
        count = 0
        while True:
            kind, key = cur.next()
            if kind == "end_map":
                break
            if key in ("type", "features"):
                self._once(key, seen, "the document")
            if key == "type":
                found = cur.build(cur.next(), Budget(0))
                if self.doc_type is None:
                    self.doc_type = found if isinstance(found, str) else ""
                continue
            if self.doc_type is None and key in ("features", "geometry", "properties"):
                self.doc_type = _document_type(self.path, self.source)
            if self.doc_type == _FEATURE and key != "features":
                cur.push_back((kind, key))
                count += yield from self._feature(0, seen & {"type"}, top=True)
                break
            if self.doc_type == _COLLECTION and key == "features":
                count += yield from self._collection()
            else:
                cur.skip(cur.next())
        cur.finish()
        if self.doc_type not in (_COLLECTION, _FEATURE):
            raise self._not_a_collection()
        if count == 0:
            raise self.error("no Point or LineString features", hint=_HINT)

    def _not_a_collection(self) -> InputError:
        return self.error("not a GeoJSON FeatureCollection or Feature", hint=_HINT)

    def _once(self, key: str, seen: set[str], where: str) -> None:
        if key in seen:
            raise self.error(f"{where} has the key {key!r} twice", hint="keep one of them")
        seen.add(key)

    def _collection(self) -> Generator[dict[str, Any], None, int]:
        cur = self.main
        first = cur.next()
        if first[0] == "null":
            return 0
        if first[0] != "start_array":
            raise self.error("'features' is not an array", hint=_HINT)
        index = 0
        count = 0
        while True:
            event = cur.next()
            if event[0] == "end_array":
                return count
            if event[0] == "start_map":
                count += yield from self._feature(index, set())
            elif event[0] != "null":
                raise self.error(f"feature {index} is not an object", hint=_HINT)
            index += 1

    # --- one feature ----------------------------------------------------------------

    def _feature(
        self, index: int, seen: set[str], top: bool = False
    ) -> Generator[dict[str, Any], None, int]:
        """Read feature ``index`` (the main cursor is inside its object; ``top``: the
        document itself) and yield its rows; return their number."""
        cur = self.main
        scanned: _Scanned | None = None
        if top:
            scanned = self._scan(cur, index, seen, top)
        else:
            cur.where = f"feature {index}"
            scanned = self._quick(index)
            cur.where = ""
        if scanned is None:  # big or unusual: read again, with care
            navigator = self.navigator("feature")
            navigator.enter(index)
            scanned = self._scan(navigator.cursor, index, seen, top)
        kind = scanned.geometry_type
        if kind == "Point":
            row = self._point(scanned)
            if row is None:
                return 0
            yield row
            return 1
        if kind in _LINES:
            return (yield from self._line(scanned, kind))
        return 0

    def _quick(self, index: int) -> _Scanned | None:
        """Feature ``index`` built in memory in one go, as :meth:`_scan` reads it; ``None``
        when that cannot be done (a container left unbuilt, a key given twice in the
        feature, its geometry or properties). Most features are read this way only."""
        cur = self.main
        budget = Budget(FEATURE_EVENTS)
        cur.repeated = False
        members = cur.members(budget)
        if budget.overdrawn or cur.repeated:
            return None
        scanned = _Scanned(index)
        keys = [k for k, _ in members if k in ("type", "geometry", "properties")]
        if len(keys) != len(set(keys)):
            return None
        where = f"feature {index}"
        for key, value in members:
            if (key != "geometry" and key != "properties") or value is None:
                continue
            if type(value) is not dict:
                raise self.error(f"{where}: {key!r} is not an object")
            if key == "properties":
                scanned.properties = value
            else:
                scanned.geometry_type = value.get("type")
                scanned.coordinates = value.get("coordinates")
        return scanned

    def _scan(self, cur: JsonCursor, index: int, seen: set[str], top: bool) -> _Scanned:
        """Read the feature the cursor is in, its big containers left for others to stream."""
        where = "the document" if top else f"feature {index}"
        budget = Budget(FEATURE_EVENTS)
        scanned = _Scanned(index)
        while True:
            kind, key = cur.next()
            if kind == "end_map":
                return scanned
            if key != "geometry" and key != "properties":
                if key == "type":
                    self._once(key, seen, where)
                cur.skip(cur.next())
                continue
            self._once(key, seen, where)
            first = cur.next()
            if first[0] == "null":
                continue
            if first[0] != "start_map":
                raise self.error(f"{where}: {key!r} is not an object")
            members = cur.members(budget)
            if key == "properties":
                scanned.properties = _properties(members)
                continue
            keys: set[str] = set()
            for name, value in members:
                if name == "type" or name == "coordinates":
                    self._once(name, keys, f"{where}'s geometry")
                    if name == "type":
                        scanned.geometry_type = value
                    else:
                        scanned.coordinates = value

    # --- Points ---------------------------------------------------------------------

    def _point(self, scanned: _Scanned) -> dict[str, Any] | None:
        coords = scanned.coordinates
        where = f"feature {scanned.index} (Point)"
        if isinstance(coords, Unbuilt):
            cursor = self.navigator("coordinates").find(scanned.index, "geometry", "coordinates")
            position = _streamed_point(cursor, where, self.source)
        else:
            position = _point_position(coords, where, self.source)
        if position is None:
            return None
        props = scanned.properties
        far = [v for k, v in props.items() if type(v) is _Far and k not in _SKIPPED]
        if far:
            built = self.navigator("properties").values(scanned.index, far)
            props = {
                k: built[v] if type(v) is _Far else v for k, v in props.items() if k not in _SKIPPED
            }
        row = {
            k: json.dumps(v) if type(v) in _NESTED else v
            for k, v in props.items()
            if k not in _SKIPPED
        }
        row.update(position)
        return row

    # --- LineStrings ----------------------------------------------------------------

    def _line(self, scanned: _Scanned, kind: str) -> Generator[dict[str, Any], None, int]:
        props = scanned.properties
        where = f"feature {scanned.index} ({kind})"
        name = props.get("name", scanned.index)
        if isinstance(name, _Far):
            name = self.navigator("properties").values(scanned.index, [name])[name]
        track = str(name)
        times: Iterator[Any] | None = None
        chosen = next(
            (
                props[n]
                for n in TIME_ARRAYS
                if isinstance(props.get(n), list)
                or (isinstance(props.get(n), _Far) and props[n].kind == "start_array")
            ),
            None,
        )
        if isinstance(chosen, _Far):
            cursor = self.navigator("times").find(
                scanned.index, "properties", chosen.key, chosen.occurrence
            )
            times = _streamed_times(cursor, kind)
        elif chosen is not None:
            times = _time_values(chosen, kind)
        coords = scanned.coordinates
        if isinstance(coords, Unbuilt):
            cursor = self.navigator("coordinates").find(scanned.index, "geometry", "coordinates")
            vertices = _streamed_vertices(cursor, kind, where, self.source)
        else:
            vertices = _vertices(coords, kind, where, self.source)
        count = 0
        for position in vertices:
            row = {"track": track, **position}
            row["time"] = None if times is None else next(times, None)
            yield row
            count += 1
        return count


def _document_type(path: Path, source: str) -> str:
    """The top-level ``type`` of the document, read ahead by a cursor of its own (for a
    document whose ``features`` come before its ``type``); ``""`` when it has none."""
    with JsonCursor(path, source) as cur:
        if cur.next()[0] != "start_map":
            return ""
        while True:
            kind, key = cur.next()
            if kind == "end_map":
                return ""
            if key == "type":
                found = cur.build(cur.next(), Budget(0))
                return found if isinstance(found, str) else ""
            cur.skip(cur.next())


class _Navigator:
    """A cursor going forward once through a document whose features the main cursor has
    already read (so known to be well formed), to the values it left unbuilt."""

    def __init__(self, cursor: JsonCursor, doc_type: str) -> None:
        self.cursor = cursor
        self._features = _walk(cursor, doc_type)
        self._at = -1

    def enter(self, index: int) -> None:
        """Go to feature ``index``: the cursor is then inside its object."""
        while self._at < index:
            self._at = next(self._features)

    def find(self, index: int, outer: str, inner: str, occurrence: int = 1) -> JsonCursor:
        """The cursor, its next event the first of the ``occurrence``-th value of ``inner``
        in the ``outer`` object (``geometry``, ``properties``) of feature ``index``."""
        self.enter(index)
        cur = self.cursor
        while cur.next()[1] != outer:
            cur.skip(cur.next())
        cur.next()  # the object's start_map
        seen = 0
        while True:
            _, key = cur.next()
            if key == inner:
                seen += 1
                if seen == occurrence:
                    return cur
            cur.skip(cur.next())

    def values(self, index: int, wanted: list[_Far]) -> dict[_Far, Any]:
        """The property values ``wanted`` of feature ``index``, built whole."""
        self.enter(index)
        cur = self.cursor
        while cur.next()[1] != "properties":
            cur.skip(cur.next())
        cur.next()  # start_map
        todo = set(wanted)
        counts: dict[str, int] = {}
        found: dict[_Far, Any] = {}
        while todo:
            _, key = cur.next()
            counts[key] = counts.get(key, 0) + 1
            first = cur.next()
            far = _Far(key, counts[key], first[0])
            if far in todo:
                found[far] = cur.build(first)
                todo.discard(far)
            else:
                cur.skip(first)
        return found


def _walk(cur: JsonCursor, doc_type: str) -> Iterator[int]:
    """Feature by feature: yields the index of each feature with the cursor inside its
    object, and, resumed, skips what is left of it."""
    cur.next()  # the document's start_map
    if doc_type == _FEATURE:
        yield 0
        return
    while True:
        kind, key = cur.next()
        if kind == "end_map":
            return
        first = cur.next()
        if key != "features" or first[0] != "start_array":
            cur.skip(first)
            continue
        depth = cur.depth
        index = 0
        while True:
            event = cur.next()
            if event[0] == "end_array":
                break
            if event[0] == "start_map":
                yield index
                cur.skip_to(depth)
            else:
                cur.skip(event)
            index += 1


# --- values: built (small features) or streamed (big ones), to the same rows ---------


def _text(value: Any) -> Any:
    """A nested value (array, object) as its JSON text: one column, one cell."""
    return json.dumps(value) if type(value) in _NESTED else value


def _properties(members: list[tuple[str, Any]]) -> dict[str, Any]:
    """The properties as :func:`json.loads` gives them (a key given twice: its first
    place, its last value), a value left unbuilt as a :class:`_Far`."""
    out: dict[str, Any] = {}
    counts: dict[str, int] = {}
    for key, value in members:
        counts[key] = counts.get(key, 0) + 1
        out[key] = _Far(key, counts[key], value.kind) if isinstance(value, Unbuilt) else value
    return out


def _not_array(where: str, source: str) -> InputError:
    return InputError(f"{where}: 'coordinates' is not an array", source=source, hint=_HINT)


def _bad_position(where: str, source: str, vertex: int | None) -> InputError:
    what = "the coordinates are" if vertex is None else f"vertex {vertex} is"
    return InputError(
        f"{where}: {what} not a position [lon, lat] or [lon, lat, alt]",
        source=source,
        hint="each position is an array of numbers",
    )


def _bad_part(where: str, source: str, part: int) -> InputError:
    return InputError(
        f"{where}: part {part} is not an array of positions", source=source, hint=_HINT
    )


def _position(values: list[Any]) -> dict[str, Any]:
    out = {"lon": values[0], "lat": values[1]}
    if len(values) > 2:
        out["alt"] = values[2]
    return out


def _checked_position(c: Any, where: str, source: str, vertex: int | None) -> dict[str, Any]:
    if type(c) is not list or len(c) < 2 or type(c[0]) in _NESTED or type(c[1]) in _NESTED:
        raise _bad_position(where, source, vertex)
    if len(c) == 2:
        return {"lon": c[0], "lat": c[1]}
    if type(c[2]) in _NESTED:
        raise _bad_position(where, source, vertex)
    return {"lon": c[0], "lat": c[1], "alt": c[2]}


def _point_position(coords: Any, where: str, source: str) -> dict[str, Any] | None:
    if coords is None or coords == []:
        return None
    if not isinstance(coords, list):
        raise _not_array(where, source)
    return _checked_position(coords, where, source, None)


def _read_position(
    cur: JsonCursor, first: Event, where: str, source: str, vertex: int | None
) -> dict[str, Any]:
    """A position from the cursor (``first``: its first event), as :func:`_checked_position`."""
    if first[0] != "start_array":
        cur.skip(first)
        raise _bad_position(where, source, vertex)
    values: list[Any] = []
    while True:
        event = cur.next()
        if event[0] == "end_array":
            break
        if len(values) < 3:
            if event[0] == "start_map" or event[0] == "start_array":
                raise _bad_position(where, source, vertex)
            values.append(event[1])
        else:
            cur.skip(event)
    if len(values) < 2:
        raise _bad_position(where, source, vertex)
    return _position(values)


def _streamed_point(cur: JsonCursor, where: str, source: str) -> dict[str, Any] | None:
    first = cur.next()
    if first[0] != "start_array":
        raise _not_array(where, source)
    second = cur.next()
    if second[0] == "end_array":
        return None  # [] like a missing position
    cur.push_back(second)
    return _read_position(cur, first, where, source, None)


def _vertices(coords: Any, kind: str, where: str, source: str) -> Iterator[dict[str, Any]]:
    if coords is None:
        return
    if not isinstance(coords, list):
        raise _not_array(where, source)
    if kind == "LineString":
        for i, c in enumerate(coords):
            yield _checked_position(c, where, source, i)
        return
    vertex = 0
    for part, line in enumerate(coords):
        if not isinstance(line, list):
            raise _bad_part(where, source, part)
        for c in line:
            yield _checked_position(c, where, source, vertex)
            vertex += 1


def _streamed_vertices(
    cur: JsonCursor, kind: str, where: str, source: str
) -> Iterator[dict[str, Any]]:
    first = cur.next()
    if first[0] == "null":
        return
    if first[0] != "start_array":
        raise _not_array(where, source)
    vertex = 0
    part = 0
    while True:
        event = cur.next()
        if event[0] == "end_array":
            return
        if kind == "LineString":
            yield _read_position(cur, event, where, source, vertex)
            vertex += 1
            continue
        if event[0] != "start_array":
            raise _bad_part(where, source, part)
        while True:
            inner = cur.next()
            if inner[0] == "end_array":
                break
            yield _read_position(cur, inner, where, source, vertex)
            vertex += 1
        part += 1


def _time_values(times: list[Any], kind: str) -> Iterator[Any]:
    """A per-vertex time array's entries; a MultiLineString's array of arrays (its
    first entry an array) part after part, an entry that is no array as one time."""
    if kind == "MultiLineString" and times and isinstance(times[0], list):
        for part in times:
            if isinstance(part, list):
                yield from (_text(t) for t in part)
            else:
                yield _text(part)
        return
    yield from (_text(t) for t in times)


def _streamed_times(cur: JsonCursor, kind: str) -> Iterator[Any]:
    """:func:`_time_values` from the cursor, at the array's first event."""
    cur.next()  # start_array
    event = cur.next()
    nested = kind == "MultiLineString" and event[0] == "start_array"
    while event[0] != "end_array":
        if nested and event[0] == "start_array":
            while (inner := cur.next())[0] != "end_array":
                yield _text(cur.build(inner))
        else:
            yield _text(cur.build(event))
        event = cur.next()
