"""ROS bags as table sources: one topic of a ROS 1 `.bag` or a ROS 2 bag folder (sqlite3 or
MCAP, with its metadata.yaml), read with rosbags' AnyReader into the same table text a CSV
file gives (recorded.py), so the rules after the reading are the CSV's: columns, units,
`start`, `offset`.

    table: {file: logs/day1, topic: /cmd_vel, start: first_row}

- VelocitySource: geometry_msgs/Twist or TwistStamped; PathFollower and a recorded pose:
  nav_msgs/Odometry or geometry_msgs/PoseStamped.
- The text's columns are the message's fields in ROS's frame (REP 103: x forward, y left):
  `time,linear.x,linear.y,angular.z` or `time,position.x,position.y,yaw` (yaw from the
  orientation, unwrapped). The default `columns` map them into ours (docs/conventions.md):
  vx = -linear.y, vy = linear.x, w = angular.z; x = -position.y, y = position.x, theta = yaw.
- `time` [s]: the header stamp where the message has one, else the log time; `stamps: log`
  takes the log time always. Times must increase. `start: bag_start` puts the bag's first
  message (of any topic: its topics stay aligned) at the start_time; `first_row` the topic's.
- A bag's problem is one line naming the bag, the topic and the fix.
"""
from __future__ import annotations

import math
import os
import stat
from pathlib import Path
from typing import Callable, Iterator

from ..errors import Problem
from ..models.blocks.profile_table import PATH_COLUMNS, TABLE_COLUMNS
from .recorded import TableSource

BAG_KEYS = ("topic", "stamps")
_DAMAGED = ("it is damaged or truncated: copy it again, or reindex it (`rosbag reindex` a "
            "ROS 1 .bag, `ros2 bag reindex` a ROS 2 folder)")
MAX_MESSAGES = 1_000_000        # a table's row limit (blocks/profile_table.py)
_TWIST = ("linear.x", "linear.y", "angular.z")
_POSE = ("position.x", "position.y", "yaw")
# per table model: the message types it reads, the fields, our columns from them
KINDS = {
    TABLE_COLUMNS: (("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"), _TWIST,
                    {"time": "time", "vx": "-linear.y", "vy": "linear.x", "w": "angular.z"}),
    PATH_COLUMNS: (("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped"), _POSE,
                   {"time": "time", "x": "-position.y", "y": "position.x", "theta": "yaw"}),
}
Report = Callable[[Problem], None]


class BagError(ValueError):
    """A bag that cannot be used; the message says what and how to fix it."""


def is_bag(raw: dict, scenario_dir: Path) -> bool:
    """Whether a `table:` mapping names a bag: a `topic`, a folder or a .bag/.mcap/.db3 file."""
    path = scenario_dir / str(raw.get("file", ""))
    return "topic" in raw or path.suffix.lower() in (".bag", ".mcap", ".db3") or path.is_dir()


def read_bag_table(raw: dict, columns: tuple[str, ...], scenario_dir: Path, start_time: float,
                   label: str, place: str, report: Report) -> tuple[TableSource, dict] | None:
    """The table text of the bag topic `raw` names, and `raw` with the bag's default columns
    (ROS's frame into ours) under the ones it gives; None and one reported problem when the
    bag or the topic cannot be used."""
    if not _options_ok(raw, place, label, report):
        return None
    path = scenario_dir / raw["file"]
    where = f"{path} {raw['topic']}"
    try:
        rows = read_topic(path, raw["topic"], KINDS[columns][0], raw.get("stamps") == "log",
                          raw.get("start") == "bag_start")
    except BagError as err:
        report(Problem(str(path)[:300], f"topic {str(raw['topic'])[:100]}",
                       f"{err} (the table of {label}: {place})"))
        return None
    fields = KINDS[columns][1]
    text = "time," + ",".join(fields) + "\n" + "".join(
        ",".join(map(repr, row)) + "\n" for row in rows)
    mapped = dict(raw, columns=KINDS[columns][2] | dict(raw.get("columns") or {}))
    if raw.get("start") == "bag_start":     # the times start at the bag's first message
        del mapped["start"]
        mapped["offset"] = start_time + float(raw.get("offset", 0))
    return TableSource(text, where, True), mapped


def _options_ok(raw: dict, place: str, label: str, report: Report) -> bool:
    ok = True
    if not isinstance(raw.get("topic"), str) or not raw["topic"].startswith("/"):
        report(Problem(label, f"{place}.topic", "a bag needs the topic to read, like "
                                                "topic: /cmd_vel"))
        ok = False
    if raw.get("stamps", "header") not in ("header", "log"):
        report(Problem(label, f"{place}.stamps", "header (the message's stamp where it has "
                                                 "one, the default) or log (the log time)"))
        ok = False
    if "time" in (raw.get("units") or {}):
        report(Problem(label, f"{place}.units.time", "a bag's times are its stamps, in "
                                                     "seconds; leave units.time out"))
        ok = False
    return ok


def bag_path(path: Path) -> Path:
    """The path rosbags opens: a ROS 1 .bag file, or the ROS 2 bag folder (a .mcap or .db3
    inside one names its folder). Raises BagError when it is neither."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise BagError("not found (the path is relative to the scenario file)") from None
    except OSError as err:
        raise BagError(f"cannot be read: {err.strerror or err}") from None
    if stat.S_ISDIR(info.st_mode) or path.suffix.lower() in (".mcap", ".db3"):
        folder = path if stat.S_ISDIR(info.st_mode) else path.parent
        meta = folder / "metadata.yaml"
        if not meta.is_file():
            raise BagError(f"the folder {str(folder)[:300]} has no metadata.yaml, so it is "
                           "not a ROS 2 bag; point at the folder `ros2 bag record` wrote, or "
                           "recreate the file with `ros2 bag reindex <folder>`")
        return folder
    if not stat.S_ISREG(info.st_mode):
        raise BagError("is not a regular file (a pipe, device or socket); give a ROS 1 .bag "
                       "file or a ROS 2 bag folder")
    if path.suffix.lower() != ".bag":
        raise BagError("is not a bag: give a ROS 1 .bag file or a ROS 2 bag folder (with "
                       "its metadata.yaml)")
    return path


def read_topic(path: Path, topic: str, types: tuple[str, ...], log_time: bool = False,
               from_bag_start: bool = False) -> list[tuple[float, ...]]:
    """(time [s], field values...) of each message on `topic` in the bag at `path`, in the
    bag's order; the time from the bag's first message (any topic) with from_bag_start. Raises BagError: no such topic (the topics there are listed), another
    message type, no messages, a truncated or damaged bag, stamps that do not increase."""
    from rosbags.highlevel import AnyReader, AnyReaderError   # startup: only for bags
    from rosbags.typesys import Stores, get_typestore
    opened = bag_path(path)
    try:
        with AnyReader([opened], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            connections = _connections(reader, topic, types)
            zero = reader.start_time if from_bag_start else 0
            rows = list(_rows(reader, connections, log_time, zero))
    except (AnyReaderError, FileNotFoundError) as err:
        raise BagError(f"cannot be opened ({_reason(err)}); {_DAMAGED}") from None
    except BagError:
        raise
    except Exception as err:   # rosbags' readers and deserializers raise many kinds
        raise BagError(f"cannot be read ({type(err).__name__}: {_reason(err)}); "
                       f"{_DAMAGED}") from None
    if not rows:
        raise BagError(f"has no messages on {topic}; record the topic, or name one that "
                       "has messages")
    _check_times(rows, topic)
    return _unwrapped(rows)


def _unwrapped(rows: list[tuple[float, ...]]) -> list[tuple[float, ...]]:
    """A pose's yaw column unwrapped: a heading crossing +-pi stays continuous."""
    if len(rows[0]) != 4:
        return rows
    import numpy as np
    yaw = np.unwrap([row[3] for row in rows]).tolist()
    return [(*row[:3], y) for row, y in zip(rows, yaw)]


def _reason(err: Exception) -> str:
    return " ".join(str(err).split())[:200] or type(err).__name__


def _connections(reader, topic: str, types: tuple[str, ...]) -> list:
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        there = ", ".join(f"{name} ({info.msgtype})"
                          for name, info in sorted(reader.topics.items())) or "none"
        raise BagError(f"no topic {topic} in the bag; its topics: {there[:600]}")
    wrong = sorted({c.msgtype for c in found} - set(types))
    if wrong:
        raise BagError(f"{topic} holds {', '.join(wrong)}; this table reads "
                       f"{' or '.join(types)}: name a topic of that type")
    if sum(c.msgcount for c in found) > MAX_MESSAGES:
        raise BagError(f"{topic} has more than {MAX_MESSAGES} messages (a table's limit); "
                       "cut the bag (`ros2 bag convert` or rosbags-convert)")
    return found


def _rows(reader, connections: list, log_time: bool,
          zero: int) -> Iterator[tuple[float, ...]]:
    for connection, logged, data in reader.messages(connections=connections):
        msg = reader.deserialize(data, connection.msgtype)
        header = getattr(msg, "header", None)
        ns = logged if header is None or log_time else \
            header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
        yield ((ns - zero) / 1e9, *_values(msg))


def _values(msg) -> tuple[float, ...]:
    """The table's fields of a twist or a pose message (ROS's frame)."""
    if hasattr(msg, "twist") and not hasattr(msg, "pose"):      # TwistStamped
        msg = msg.twist
    if hasattr(msg, "linear"):
        return msg.linear.x, msg.linear.y, msg.angular.z
    pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose     # Odometry
    q = pose.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return pose.position.x, pose.position.y, yaw


def _check_times(rows: list[tuple[float, ...]], topic: str) -> None:
    """Stamps that go back or repeat, or values that are not finite, named at the first such
    message (and counted)."""
    back = [i for i in range(1, len(rows)) if not rows[i][0] > rows[i - 1][0]]
    if back:
        i = back[0]
        raise BagError(f"the stamps of {topic} go back or repeat at message {i + 1} "
                       f"({rows[i][0]!r} s after {rows[i - 1][0]!r} s; {len(back)} such "
                       "message(s)): give stamps: log to use the log time, or fix the "
                       "recorder's clock")
    bad = [i for i, row in enumerate(rows) if not all(math.isfinite(v) for v in row)]
    if bad:
        raise BagError(f"message {bad[0] + 1} of {topic} has a value that is not a finite "
                       f"number ({len(bad)} such message(s)); cut them from the bag")
