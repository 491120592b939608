"""`run --bag`: the run as a ROS 2 bag (MCAP storage, with its metadata.yaml) in <out>/bag/,
for Foxglove, RViz (`ros2 bag play`) and any rosbag2 reader. Written by rosbags' writer from
results.csv (every row), stamped on the run's time (t = 0 s is stamp 0), in ROS's frame
(REP 103; docs/conventions.md: a point (x, y) of ours is ROS's (y, -x), yaw = theta, a twist
(vx, vy, w) is linear (vy, -vx), angular.z = w):

- /<pose>/odom   nav_msgs/msg/Odometry of each PoseIntegrator: world -> <pose>/base_link,
                 the twist it integrates in its body frame
- /tf            tf2_msgs/msg/TFMessage: world -> <pose>/base_link of every pose, each step
- /<pose>/cmd_vel  geometry_msgs/msg/TwistStamped: the commanded twist of what drives it
                 (VelocitySource, PathFollower)

The bag is written in `.bag.part/` and renamed to `bag/` when whole; only a complete run
writes one, so a `bag/` folder is always a whole run. A run's old `bag/` is removed when the
next run into the folder starts.
"""
from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import numpy as np

from .errors import Problem, ScenarioError

WORLD = "world"
FOLDER = "bag"
MARK = "mecanum_fmu"            # metadata.yaml custom_data: this project wrote the bag
_PART = ".bag.part"


def remove_previous(out_dir: Path) -> None:
    """An earlier run's bag/ and a left-over .bag.part/ (ours only: marked in metadata.yaml)."""
    part = out_dir / _PART
    if part.is_dir() and not part.is_symlink():
        shutil.rmtree(part)
    bag = out_dir / FOLDER
    meta = bag / "metadata.yaml"
    if bag.is_dir() and not bag.is_symlink() and meta.is_file() \
            and f"writer: {MARK}" in meta.read_text(errors="replace"):
        shutil.rmtree(bag)


def check_room(out_dir: Path) -> None:
    """Before the run: a bag/ that is not ours (remove_previous took ours) is bad input."""
    if (out_dir / FOLDER).exists() or (out_dir / FOLDER).is_symlink():
        raise ScenarioError([Problem(str(out_dir / FOLDER), "--bag", "is in the way (not a "
                                     "bag this project wrote); move it or choose another "
                                     "--out")])


def pose_columns(names: tuple[str, ...], drives) -> list[dict]:
    """Per pose: its name and the recorded columns of its pose, its body twist (what feeds
    its vx, vy, w) and its command (the drive's origin), each None when not recorded."""
    out = []
    for drive in drives:
        pose = [f"{drive.pose}.{v}" for v in ("x", "y", "theta")]
        feed = drive.chain[0] if drive.chain else drive.origin
        body = [f"{feed}.{v}" for v in ("vx", "vy", "w")]
        cmd = [f"{drive.origin}.{v}" if drive.origin else None for v in ("vx", "vy", "w")]
        out.append({"pose": drive.pose,
                    "xy": pose if all(c in names for c in pose) else None,
                    "body": body if all(c in names for c in body) else None,
                    "cmd": cmd if all(c in names for c in cmd) and drive.origin else None})
    return [p for p in out if p["xy"] is not None]


def write_run_bag(results_csv: Path, drives, out_dir: Path) -> dict:
    """Write <out_dir>/bag/ from results.csv; what it holds (for summary.json)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_HUMBLE)
    header = results_csv.open().readline().strip().split(",")
    data = np.loadtxt(results_csv, delimiter=",", skiprows=1, ndmin=2)
    column = {name: data[:, i] for i, name in enumerate(header)}
    poses = pose_columns(tuple(header), drives)
    part, final = out_dir / _PART, out_dir / FOLDER
    counts: dict[str, int] = {}
    try:
        part.mkdir()        # the bag is written as .bag.part/bag/ (its file: bag.mcap)
        with Writer(part / FOLDER, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            writer.set_custom_data("writer", MARK)
            _write_messages(writer, store, column, poses, counts)
        if final.exists():
            raise FileExistsError(f"{final} is in the way (a folder this project did not "
                                  "write); move it or choose another --out")
        os.replace(part / FOLDER, final)
    finally:
        if part.exists():
            shutil.rmtree(part, ignore_errors=True)
    return {"folder": FOLDER, "storage": "mcap", "frame": WORLD, "topics": counts}


def _write_messages(writer, store, column: dict, poses: list[dict], counts: dict) -> None:
    T = store.types
    links = {}

    def put(topic: str, msgtype: str, ns: int, msg) -> None:
        if topic not in links:
            links[topic] = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(links[topic], ns, store.serialize_cdr(msg, msgtype))
        counts[topic] = counts.get(topic, 0) + 1

    for i, t in enumerate(column["time"].tolist()):
        ns = round(t * 1e9)
        stamp = T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)
        frames = []
        for p in poses:
            base = f"{p['pose']}/base_link"
            x, y, theta = (float(column[c][i]) for c in p["xy"])
            frames.append(_transform(T, stamp, base, x, y, theta))
            body = _twist(T, *(float(column[c][i]) for c in p["body"])) if p["body"] \
                else _twist(T, 0.0, 0.0, 0.0)
            put(f"/{p['pose']}/odom", "nav_msgs/msg/Odometry", ns,
                _odometry(T, stamp, base, x, y, theta, body))
            if p["cmd"]:
                put(f"/{p['pose']}/cmd_vel", "geometry_msgs/msg/TwistStamped", ns,
                    T["geometry_msgs/msg/TwistStamped"](
                        T["std_msgs/msg/Header"](stamp, base),
                        _twist(T, *(float(column[c][i]) for c in p["cmd"]))))
        put("/tf", "tf2_msgs/msg/TFMessage", ns, T["tf2_msgs/msg/TFMessage"](frames))


def _twist(T, vx: float, vy: float, w: float):
    """Our body twist in ROS's axes: linear.x = vy (forward), linear.y = -vx (left)."""
    vector = T["geometry_msgs/msg/Vector3"]
    return T["geometry_msgs/msg/Twist"](vector(vy, -vx, 0.0), vector(0.0, 0.0, w))


def _quaternion(T, theta: float):
    return T["geometry_msgs/msg/Quaternion"](0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))


def _transform(T, stamp, base: str, x: float, y: float, theta: float):
    """world -> base of our pose (x right, y forward) in ROS's world axes: (y, -x)."""
    return T["geometry_msgs/msg/TransformStamped"](
        T["std_msgs/msg/Header"](stamp, WORLD), base,
        T["geometry_msgs/msg/Transform"](T["geometry_msgs/msg/Vector3"](y, -x, 0.0),
                                         _quaternion(T, theta)))


def _odometry(T, stamp, base: str, x: float, y: float, theta: float, body):
    covariance = np.zeros(36)
    pose = T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](y, -x, 0.0),
                                       _quaternion(T, theta))
    return T["nav_msgs/msg/Odometry"](
        T["std_msgs/msg/Header"](stamp, WORLD), base,
        T["geometry_msgs/msg/PoseWithCovariance"](pose, covariance),
        T["geometry_msgs/msg/TwistWithCovariance"](body, covariance.copy()))
