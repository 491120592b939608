"""Write an example ROS 2 bag and a scenario that replays it (docs/bags.md).

    .venv/bin/python docs/bag_example.py [FOLDER]      # default: results/bag_example

FOLDER/day1/ is a ROS 2 bag (MCAP storage, metadata.yaml) as a robot would record it, written
with rosbags' writer: the seed's commands (vx = sin t, vy = cos t, w = 0 in this project's
frame) on /cmd_vel as geometry_msgs/msg/Twist in ROS's axes (linear.x = cos t forward,
linear.y = -sin t left), and the closed-form pose (x = 1 - cos t, y = sin t ours; ROS
position (sin t, -(1 - cos t))) on /odom as nav_msgs/msg/Odometry, both at 50 Hz for 10 s,
logged on a wall clock (stamps from 2023-11-14 22:13:20 UTC). FOLDER/day1.yaml drives the
seed's chain from /cmd_vel and holds the simulated pose against /odom.
"""
import math
import shutil
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

RATE, SECONDS, EPOCH = 50, 10.0, 1_700_000_000
SCENARIO = """\
name: day1
description: "The seed's commands replayed from a ROS 2 bag, held against its /odom"
experiment: {start_time: 0.0, stop_time: 10.0, step_size: 0.05}
parameters: {alpha: 0.7853981633974483, L: 0.16, W: 0.12, R: 0.06}
components:
  source: {fmu: VelocitySource, table: {file: day1, topic: /cmd_vel, start: bag_start}}
  c2w: {fmu: Center2Wheel}
  w2c: {fmu: Wheel2Center}
  pose: {fmu: PoseIntegrator}
recorded:
  pose: {file: day1, topic: /odom, start: bag_start}
connections:
  - [source.vx, c2w.vx]
  - [source.vy, c2w.vy]
  - [source.w,  c2w.w]
  - [c2w.w1, w2c.w1]
  - [c2w.w2, w2c.w2]
  - [c2w.w3, w2c.w3]
  - [c2w.w4, w2c.w4]
  - [w2c.vx, pose.vx]
  - [w2c.vy, pose.vy]
  - [w2c.w,  pose.w]
"""


def messages(store):
    T = store.types
    vector, zeros = T["geometry_msgs/msg/Vector3"], np.zeros(36)
    for i in range(int(SECONDS * RATE) + 1):
        t = i / RATE
        ns = EPOCH * 10**9 + i * 10**9 // RATE
        twist = T["geometry_msgs/msg/Twist"](vector(math.cos(t), -math.sin(t), 0.0),
                                             vector(0.0, 0.0, 0.0))
        yield "/cmd_vel", "geometry_msgs/msg/Twist", ns, twist
        pose = T["geometry_msgs/msg/Pose"](
            T["geometry_msgs/msg/Point"](math.sin(t), -(1 - math.cos(t)), 0.0),
            T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0))
        header = T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](ns // 10**9,
                                                                           ns % 10**9), "odom")
        yield "/odom", "nav_msgs/msg/Odometry", ns, T["nav_msgs/msg/Odometry"](
            header, "base_link", T["geometry_msgs/msg/PoseWithCovariance"](pose, zeros),
            T["geometry_msgs/msg/TwistWithCovariance"](twist, zeros))


def main(folder: Path) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    folder.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(folder / "day1", ignore_errors=True)
    links = {}
    with Writer(folder / "day1", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic, msgtype, ns, msg in messages(store):
            if topic not in links:
                links[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(links[topic], ns, store.serialize_cdr(msg, msgtype))
    (folder / "day1.yaml").write_text(SCENARIO)
    print(f"wrote {folder / 'day1'}/ (/cmd_vel, /odom) and {folder / 'day1.yaml'}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "results/bag_example"))
