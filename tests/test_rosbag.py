"""ROS bags: write small ROS 1 and ROS 2 bags with rosbags' writers, read them back."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._exceptions import InputError
from gradgps._io.read import read_table
from gradgps._io.rosbag import NAVSATFIX, TWIST_STAMPED, read_rosbag
from gradgps._tracks.track import to_fixes

pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from _rosbag_support import T0, N, write_drive
from _whole_file import detect_whole


def _check(table):
    assert len(table.frame) == N
    frame = table.frame
    np.testing.assert_allclose(frame["time"], T0 + np.arange(N))
    assert math.isnan(frame["lat"].iloc[7])
    assert frame["status"].iloc[7] == -1
    np.testing.assert_allclose(frame["speed"], 10.0)  # hypot(6, 8), vertical ignored
    fixes = to_fixes(table)
    assert list(fixes.columns[:6]) == ["track", "t", "lat", "lon", "speed", "alt"]
    assert fixes["lat"].iloc[3] == pytest.approx(48.0 + 3 * 9e-5)


def test_ros1_bag(tmp_path):
    store = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "drive.bag"
    with Writer1(path) as writer:
        write_drive(writer, store, store.serialize_ros1)
    _check(read_table(path))


@pytest.mark.parametrize("plugin", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_ros2_bag_directory_and_storage_file(tmp_path, plugin):
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "drive"
    with Writer2(path, version=9, storage_plugin=plugin) as writer:
        write_drive(writer, store, store.serialize_cdr)
    _check(read_table(path))
    storage = next(path.glob("*.mcap" if plugin == StoragePlugin.MCAP else "*.db3"))
    _check(read_table(storage))


def test_several_receivers_are_tracks_and_topics_can_be_named(tmp_path):
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "two"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        write_drive(writer, store, store.serialize_cdr, extra_topic=True)
    fixes = to_fixes(read_table(path))
    assert sorted(set(fixes["track"])) == ["/gps/fix", "/rtk/fix"]
    assert len(read_rosbag(path, fix_topic="/rtk/fix").frame) == 5
    with pytest.raises(InputError, match="not a sensor_msgs/msg/NavSatFix topic"):
        read_rosbag(path, fix_topic="/gps/vel")


def test_detect_cli_reads_a_bag(tmp_path):
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "drive"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        write_drive(writer, store, store.serialize_cdr)
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert f"{N} rows" in result.output
    assert "1 invalid" in result.output  # the no-fix message


def test_bag_without_fixes_says_what_it_has(tmp_path):
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "empty"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.add_connection("/gps/vel", TWIST_STAMPED, typestore=store)
    with pytest.raises(InputError, match=r"no sensor_msgs/msg/NavSatFix topic.*/gps/vel"):
        read_table(path)


def test_speed_is_the_nearest_twist_within_the_lag():
    from gradgps._io.rosbag import _speeds

    got = _speeds(np.array([0.0, 1.0, 2.0, 5.0]), [3.0, 0.9, 0.1], [3.0, 2.0, 1.0], 0.5)
    np.testing.assert_array_equal(got[:3], [1.0, 2.0, np.nan])
    assert np.isnan(got[3])


def test_a_damaged_metadata_yaml_is_one_error_line(tmp_path):
    """The YAML parser's message spans several lines (the line, a caret under the column);
    on main it went into the error as is, so `gradgps detect` printed a multi-line error.
    Found by test_fuzz_ros2_bag_bytes."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "drive"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        write_drive(writer, store, store.serialize_cdr)
    metadata = path / "metadata.yaml"
    text = metadata.read_text()
    metadata.write_text(
        text.replace("rosbag2_bagfile_information:", "rosbag2_bagfile_information: -1", 1)
    )
    with pytest.raises(InputError, match="cannot read the ROS bag") as caught:
        read_table(path)
    assert "\n" not in str(caught.value)
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "out.csv")])
    assert result.exit_code == 2  # bad input, as click's usage errors
    assert result.output.strip().startswith("error: ")
    assert len(result.output.strip().splitlines()) == 1


@pytest.mark.parametrize("chunk", [1, 4, 7, 1000])
def test_a_bag_read_in_chunks_gives_the_whole_bag(tmp_path, chunk):
    """Issue 18: a bag is read message by message into chunks (two passes: twist speeds
    first, then the fixes), so memory is one chunk and the twists, not the bag; the chunks
    join to the whole-bag table (two receivers interleaved, speeds from twists that come
    after their fix in the bag), and detect gives the bytes of the bag read whole and
    detected at once (``detect_whole``; --chunk-size 0 reads the largest chunks)."""
    import pandas as pd

    from gradgps._io.read import table_chunks

    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "two"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        write_drive(writer, store, store.serialize_cdr, extra_topic=True)
    whole = read_table(path)
    chunks = table_chunks(path, chunk)
    assert chunks.n_rows == len(whole.frame) == N + 5
    tables = list(chunks)
    assert [t.row_offset for t in tables] == list(range(0, N + 5, chunk))
    assert all(t.columns == whole.columns for t in tables)
    pd.testing.assert_frame_equal(
        pd.concat([t.frame for t in tables], ignore_index=True), whole.frame
    )
    whole_out = tmp_path / "whole.csv"
    detect_whole(path, whole_out)
    for size in (str(chunk), "0"):
        out = tmp_path / f"out{size}.csv"
        done = CliRunner().invoke(main, ["detect", str(path), "-o", str(out), "--chunk-size", size])
        assert done.exit_code == 0, done.output
        assert out.read_bytes() == whole_out.read_bytes(), size


# --- ROS 1 bags read by gradgps._io.rosbag1 (issue 18: bounded memory) -------------------


def _ros1_bag(path, records, *, chunk_threshold=1 << 20, compression=None):
    """A ROS 1 bag of ``records`` ((topic, type, record ns, stamp ns), written in that order)
    with rosbags' Writer: NavSatFix with a made-up position, TwistStamped with a speed."""
    store = get_typestore(Stores.ROS1_NOETIC)
    T = store.types
    writer = Writer1(path)
    if compression is not None:
        writer.set_compression(compression)
    writer.chunk_threshold = chunk_threshold
    with writer:
        conns = {}
        for k, (topic, kind, ns, stamp) in enumerate(records):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, kind, typestore=store)
            header = T["std_msgs/msg/Header"](
                seq=k,
                stamp=T["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9),
                frame_id="gps",
            )
            if kind == TWIST_STAMPED:
                v = T["geometry_msgs/msg/Vector3"]
                msg = T[TWIST_STAMPED](
                    header=header,
                    twist=T["geometry_msgs/msg/Twist"](
                        linear=v(x=float(k % 7), y=1.0, z=0.0), angular=v(x=0.0, y=0.0, z=0.0)
                    ),
                )
            else:
                msg = T[NAVSATFIX](
                    header=header,
                    status=T["sensor_msgs/msg/NavSatStatus"](
                        status=-1 if k % 11 == 3 else k % 3, service=1
                    ),
                    latitude=48.0 + k * 1e-5,
                    longitude=11.0 - k * 1e-5,
                    altitude=float(k),
                    position_covariance=np.zeros(9),
                    position_covariance_type=0,
                )
            writer.write(conns[topic], ns, store.serialize_ros1(msg, kind))
    return path


def _rosbags_open_bag(bag):
    """gradgps's reader before issue 18's ROS 1 reader: rosbags' AnyReader for every bag."""
    from contextlib import contextmanager

    from rosbags.highlevel import AnyReader

    @contextmanager
    def opened():
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            yield reader

    return opened()


def _assert_read_as_rosbags_reads(path, monkeypatch, **kwargs):
    """Messages (connection, time, bytes, in order) and the fixes' table equal rosbags'."""
    from rosbags.highlevel import AnyReader

    from gradgps._io import rosbag as rosbag_module
    from gradgps._io.rosbag1 import Ros1Bag

    with AnyReader([path]) as theirs, Ros1Bag(path) as ours:
        assert [(c.id, c.topic, c.msgtype) for c in ours.connections] == [
            (c.id, c.topic, c.msgtype) for c in theirs.connections
        ]
        for picked in (
            list(range(len(ours.connections))),
            list(range(len(ours.connections)))[::-1],
        ):
            asked = [ours.connections[k] for k in picked]
            asked_theirs = [theirs.connections[k] for k in picked]
            got = [(c.topic, t, bytes(raw)) for c, t, raw in ours.messages(connections=asked)]
            want = [(c.topic, t, bytes(raw)) for c, t, raw in theirs.messages(asked_theirs)]
            assert got == want
    if not any(c.msgtype == NAVSATFIX for c in ours.connections):
        return None
    ours_table = read_rosbag(path, **kwargs)
    monkeypatch.setattr(rosbag_module, "_open_bag", _rosbags_open_bag)
    theirs_table = read_rosbag(path, **kwargs)
    monkeypatch.undo()
    pd.testing.assert_frame_equal(ours_table.frame, theirs_table.frame)
    assert ours_table.columns == theirs_table.columns
    assert ours_table.notes == theirs_table.notes
    return ours_table


def _interleaved(n=400, topics=("/gps/fix", "/rtk/fix", "/gps/vel", "/gps/fix2")):
    """Several connections interleaved in time order, a few record times shared (ties)."""
    kinds = {t: TWIST_STAMPED if t.endswith("vel") else NAVSATFIX for t in topics}
    records = []
    for k in range(n):
        topic = topics[k % len(topics)]
        ns = T0 * 10**9 + (k // 3) * 10**8  # three messages a record time: ties across topics
        records.append((topic, kinds[topic], ns, ns + 5_000_000 * (k % 5)))
    return records


@pytest.mark.parametrize("compression", [None, "BZ2", "LZ4"])
@pytest.mark.parametrize("chunk_threshold", [1 << 20, 3000, 1])
def test_ros1_reader_gives_rosbags_messages_and_rows(
    tmp_path, monkeypatch, compression, chunk_threshold
):
    """Issue 18: ROS 1 bags are read by gradgps._io.rosbag1, not rosbags' reader (its index
    held ~160 bytes a message): the same messages in the same order (ties across topics broken
    as rosbags breaks them, for either order of the connections asked for) and the same rows,
    in one chunk or many, none, bz2 or lz4 compressed."""
    fmt = None if compression is None else getattr(Writer1.CompressionFormat, compression)
    path = _ros1_bag(
        tmp_path / "i.bag", _interleaved(), chunk_threshold=chunk_threshold, compression=fmt
    )
    table = _assert_read_as_rosbags_reads(path, monkeypatch, twist_topic="/gps/vel")
    assert len(table.frame) == 300


@pytest.mark.parametrize("compression", [None, "BZ2", "LZ4"])
def test_ros1_reader_orders_out_of_order_chunks_as_rosbags(tmp_path, monkeypatch, compression):
    """Record times shuffled across chunks (each chunk's range overlapping others, more chunks
    than the reader's cache holds), with many ties within and across connections; and bags
    whose chunks are in reverse time order or overlap at one time only."""
    rng = np.random.default_rng(18)
    fmt = None if compression is None else getattr(Writer1.CompressionFormat, compression)
    records = _interleaved(600)
    shuffled = [records[k] for k in rng.permutation(len(records))]
    shuffled = [
        (t, kind, T0 * 10**9 + int(rng.integers(0, 40)) * 10**9, s) for t, kind, _, s in shuffled
    ]
    path = _ros1_bag(tmp_path / "shuffled.bag", shuffled, chunk_threshold=1500, compression=fmt)
    _assert_read_as_rosbags_reads(path, monkeypatch)
    backwards = sorted(records, key=lambda r: -r[2])
    path = _ros1_bag(tmp_path / "back.bag", backwards, chunk_threshold=2000, compression=fmt)
    _assert_read_as_rosbags_reads(path, monkeypatch)
    # Chunks that touch: the last time of one chunk is the first of the next, other topics.
    touching = [
        (t, kind, T0 * 10**9 + (k // 10) * 10**9, s) for k, (t, kind, _, s) in enumerate(records)
    ]
    path = _ros1_bag(tmp_path / "touch.bag", touching, chunk_threshold=1000, compression=fmt)
    _assert_read_as_rosbags_reads(path, monkeypatch)


def test_ros1_reader_on_empty_bags(tmp_path, monkeypatch):
    """A bag with no messages (connections only, or nothing) reads as rosbags reads it."""
    store = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "conn.bag"
    with Writer1(path) as writer:
        writer.add_connection("/gps/fix", NAVSATFIX, typestore=store)
    assert len(_assert_read_as_rosbags_reads(path, monkeypatch).frame) == 0
    path = tmp_path / "nothing.bag"
    with Writer1(path):
        pass
    _assert_read_as_rosbags_reads(path, monkeypatch)
    with pytest.raises(InputError, match="no sensor_msgs/msg/NavSatFix topic"):
        read_rosbag(path)


@pytest.mark.parametrize("runs", [1, 3])
def test_ros1_reader_memory_does_not_grow_with_the_bag(tmp_path, runs):
    """Issue 18: rosbags' ROS 1 reader built a Python index entry for every message when the
    bag was opened (~150 bytes a message); this reader holds a few integers a chunk and the
    index of the chunks open in its merge, so reading a bag of 4N fixes peaks about as
    reading N does (tracemalloc, rows in chunks of 500): time-ordered, or three time-ordered
    runs written one after the other (every chunk overlapping two others: a single sort of
    the bag would hold every message's entry)."""
    import tracemalloc

    from gradgps._io.rosbag import rosbag_tables

    def peak(n):
        per_run = n // runs
        records = [
            ("/gps/fix", NAVSATFIX, (T0 + k % per_run) * 10**9, (T0 + k) * 10**9) for k in range(n)
        ]
        path = _ros1_bag(tmp_path / f"{n}.bag", records, chunk_threshold=20_000)
        tracemalloc.start()
        try:
            rows = sum(len(t.frame) for t in rosbag_tables(path, 500).chunks)
            return rows, tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    n = 4200
    peak(120)  # first-call costs (imports, rosbags' caches) out of the way
    (small_rows, small), (big_rows, big) = peak(n), peak(4 * n)
    assert (small_rows, big_rows) == (n, 4 * n)
    # rosbags' reader: 1.0 and 2.95 MB (its index, ~150 bytes a message); this reader sorting
    # each group of overlapping chunks whole (commit cd98e0f): 0.93 and 1.26 MB for three
    # runs; this one: 0.48 and 0.54 MB time-ordered
    assert big - small < 200_000, (small, big)


@pytest.mark.parametrize(
    ("damage", "says"),
    [
        ("chunk_length", "over 256 MiB"),
        ("chunk_length_in_file", "past the end of the file"),
        ("declared_size", "more than its declared"),
        ("header_length", "over 1 MiB"),
        ("conn_count", "do not fit in the file"),
    ],
)
def test_ros1_lengths_are_checked_before_reading(tmp_path, damage, says):
    """A length or count field given a hostile value is refused, in one line, before anything
    is read or allocated by it (the file's size bounds every length; a chunk's declared
    size bounds its decompression)."""
    import struct

    path = _ros1_bag(
        tmp_path / "ok.bag", _interleaved(40), compression=Writer1.CompressionFormat.BZ2
    )
    data = bytearray(path.read_bytes())
    chunk = 13 + 4096  # rosbags' Writer pads the bag header record to 4096 bytes
    (header_length,) = struct.unpack_from("<L", data, chunk)
    if damage == "chunk_length":
        struct.pack_into("<L", data, chunk + 4 + header_length, 0xFFFFFFFF)
    elif damage == "chunk_length_in_file":
        struct.pack_into("<L", data, chunk + 4 + header_length, len(data))
    elif damage == "declared_size":
        at = data.index(b"size=", chunk) + 5
        struct.pack_into("<L", data, at, struct.unpack_from("<L", data, at)[0] - 1)
    elif damage == "header_length":
        struct.pack_into("<L", data, chunk, 0x7FFFFFFF)
    else:
        at = data.index(b"conn_count=") + 11
        struct.pack_into("<L", data, at, 0xFFFFFFFF)
    bad = tmp_path / "bad.bag"
    bad.write_bytes(bytes(data))
    with pytest.raises(InputError, match=says) as caught:
        read_rosbag(bad)
    assert "\n" not in str(caught.value)
