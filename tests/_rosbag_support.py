"""A small drive as ROS bag messages, for the reader's tests and the bag fuzz tests.

No ``rosbags`` import here: callers pass the type store and writer they made
(after ``pytest.importorskip("rosbags")``), so importing this never skips a module.
"""

from __future__ import annotations

import numpy as np

from gradgps._io.rosbag import NAVSATFIX, TWIST_STAMPED

T0 = 1_700_000_000
N = 30


def drive_messages(store, *, status_at: int = 7):
    """NavSatFix every second moving north at 10 m/s, TwistStamped at 10 Hz; fix 7 has no fix."""
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    Status = store.types["sensor_msgs/msg/NavSatStatus"]
    Fix = store.types[NAVSATFIX]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Twist = store.types["geometry_msgs/msg/Twist"]
    TwistStamped = store.types[TWIST_STAMPED]
    fixes, twists = [], []
    ros1 = {"seq": 0} if "seq" in Header.__dataclass_fields__ else {}

    def header(sec, nanosec=0):
        return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id="gps", **ros1)

    for i in range(N):
        status = Status(status=-1 if i == status_at else 0, service=1)
        fixes.append(
            (
                T0 + i,
                Fix(
                    header=header(T0 + i),
                    status=status,
                    latitude=48.0 + i * 9e-5,
                    longitude=11.0,
                    altitude=500.0,
                    position_covariance=np.zeros(9),
                    position_covariance_type=0,
                ),
            )
        )
    for k in range(10 * N):
        twist = Twist(linear=Vector3(x=6.0, y=8.0, z=0.5), angular=Vector3(x=0.0, y=0.0, z=0.0))
        twists.append(
            (
                T0 + k / 10,
                TwistStamped(header=header(T0 + k // 10, (k % 10) * 100_000_000), twist=twist),
            )
        )
    return fixes, twists


def write_drive(writer, store, serialize, extra_topic=False):
    """Write :func:`drive_messages` to an open rosbags ``writer`` (ROS 1 or 2: ``serialize``
    is the store's ``serialize_ros1`` or ``serialize_cdr``), in time order; ``extra_topic``
    adds a second NavSatFix topic holding the first five fixes again."""
    fixes, twists = drive_messages(store)
    fix_conn = writer.add_connection("/gps/fix", NAVSATFIX, typestore=store)
    twist_conn = writer.add_connection("/gps/vel", TWIST_STAMPED, typestore=store)
    records = [(int(t * 1e9), fix_conn, NAVSATFIX, m) for t, m in fixes]
    records += [(int(t * 1e9), twist_conn, TWIST_STAMPED, m) for t, m in twists]
    if extra_topic:
        other = writer.add_connection("/rtk/fix", NAVSATFIX, typestore=store)
        records += [(int(t * 1e9), other, NAVSATFIX, m) for t, m in fixes[:5]]
    for ns, conn, kind, msg in sorted(records, key=lambda r: r[0]):
        writer.write(conn, ns, serialize(msg, kind))
