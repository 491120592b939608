"""ROS bag cost against the bag's length: reading a Twist topic of 10^3 ... 10^5 messages
(MCAP, written here with rosbags' writer) with bags.read_topic, and `run --bag`'s writer
(bag_output.write_run_bag) on a results.csv of as many rows. Timings are of this machine under
its current load: compare the rows with each other (cost per message should stay flat).

    .venv/bin/python bench/bags.py            # 10^3, 10^4, 10^5
    .venv/bin/python bench/bags.py 20000      # chosen sizes
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from mecanum_fmu.bag_output import write_run_bag
from mecanum_fmu.scenario.bags import read_topic
from mecanum_fmu.models.topology import Drive

SIZES = (1_000, 10_000, 100_000)
TWIST = "geometry_msgs/msg/Twist"


def write_twists(path: Path, n: int) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    vector, twist = store.types["geometry_msgs/msg/Vector3"], store.types[TWIST]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        link = writer.add_connection("/cmd_vel", TWIST, typestore=store)
        for i in range(n):
            msg = twist(vector(math.cos(i / 1000), -math.sin(i / 1000), 0.0),
                        vector(0.0, 0.0, 0.0))
            writer.write(link, i * 10**6, store.serialize_cdr(msg, TWIST))


def write_results(path: Path, n: int) -> None:
    names = "time,source.vx,source.vy,source.w,w2c.vx,w2c.vy,w2c.w,pose.x,pose.y,pose.theta"
    rows = (f"{t!r},{math.sin(t)!r},{math.cos(t)!r},0.0,{math.sin(t)!r},{math.cos(t)!r},0.0,"
            f"{1 - math.cos(t)!r},{math.sin(t)!r},0.0\n" for t in (i / 1000 for i in range(n)))
    path.write_text(names + "\n" + "".join(rows))


def main(sizes) -> None:
    drive = Drive("pose", "source", "VelocitySource", ("w2c",), None)
    print("messages   read [s]  read [us/msg]   write [s]  write [us/row]")
    for n in sizes:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            write_twists(folder / "in", n)
            start = time.perf_counter()
            read_topic(folder / "in", "/cmd_vel", (TWIST,))
            read = time.perf_counter() - start
            write_results(folder / "results.csv", n)
            start = time.perf_counter()
            write_run_bag(folder / "results.csv", [drive], folder)
            write = time.perf_counter() - start
        print(f"{n:>8,}   {read:8.2f}  {read / n * 1e6:13.1f}   {write:9.2f}  "
              f"{write / n * 1e6:14.1f}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or SIZES)
