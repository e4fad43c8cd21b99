"""ROS bags: write small ROS 1 and ROS 2 bags with rosbags' writers, read them back."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._exceptions import InputError
from gradgps._io.read import read_table
from gradgps._io.rosbag import TWIST_STAMPED, read_rosbag
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
