"""ROS bags in and out (issue 32): real bags written here with rosbags' writers (ROS 1 .bag,
ROS 2 sqlite3, ROS 2 MCAP) holding the seed's commands, run as table sources; the run written
as an MCAP bag and read back with rosbags and with the `mcap` reader; each bad bag.

Reference values: the spec's end point of the seed, (1.839, -0.544) (docs/spec.md, The
original study), its closed form x = 1 - cos t, y = sin t, and the same scenario driven by the
expressions; the frame mapping of docs/conventions.md written out by hand here (ROS linear.x =
our vy, linear.y = -our vx; a point (x, y) of ours is ROS's (y, -x)).
"""
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from helpers import CHAIN_CONNECTIONS, run_main, write_scenario
from mecanum_fmu import master
from mecanum_fmu.errors import ScenarioError
from mecanum_fmu.runner import prepare

rosbags = pytest.importorskip("rosbags")   # a dependency of the project: always there
from rosbags.rosbag1 import Writer as Writer1                         # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2          # noqa: E402
from rosbags.typesys import Stores, get_typestore                     # noqa: E402

ROS1, ROS2 = get_typestore(Stores.ROS1_NOETIC), get_typestore(Stores.ROS2_HUMBLE)
RATE = 100                      # [Hz] the recorded commands
SEED_END = (1.839, -0.544)      # the spec's end point after 10 s
DELAY = 0.25                    # [s] log time after the header stamp (the stamped topics)
FORMATS = ("ros1", "sqlite3", "mcap")


def _twist(store, t):
    """The seed's command at t in ROS's frame: linear.x = our vy = cos t, linear.y = -our vx."""
    T = store.types
    return T["geometry_msgs/msg/Twist"](T["geometry_msgs/msg/Vector3"](math.cos(t), -math.sin(t), 0.0),
                                        T["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.0))


def _header(store, t, frame="base_link"):
    T = store.types
    ns = round(t * 1e9)
    stamp = T["builtin_interfaces/msg/Time"](ns // 10**9, ns % 10**9)
    if store is ROS1:
        return T["std_msgs/msg/Header"](0, stamp, frame)
    return T["std_msgs/msg/Header"](stamp, frame)


def _pose(store, t, yaw=0.0):
    """The seed's closed-form pose at t (x = 1 - cos t, y = sin t ours) in ROS's frame."""
    T = store.types
    point = T["geometry_msgs/msg/Point"](math.sin(t), -(1 - math.cos(t)), 0.0)
    turn = T["geometry_msgs/msg/Quaternion"](0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    return T["geometry_msgs/msg/Pose"](point, turn)


def _odometry(store, t, yaw=0.0):
    T = store.types
    cov = np.zeros(36)
    return T["nav_msgs/msg/Odometry"](
        _header(store, t, "odom"), "base_link",
        T["geometry_msgs/msg/PoseWithCovariance"](_pose(store, t, yaw), cov),
        T["geometry_msgs/msg/TwistWithCovariance"](_twist(store, t), cov))


def seed_messages(store, seconds=10.0, rate=RATE):
    """(topic, type, log time [ns], message) of the seed's commands and pose."""
    T = store.types
    for i in range(int(seconds * rate) + 1):
        t = i / rate
        ns = round(t * 1e9)
        yield "/cmd_vel", "geometry_msgs/msg/Twist", ns, _twist(store, t)
        yield ("/cmd_vel_stamped", "geometry_msgs/msg/TwistStamped", ns + round(DELAY * 1e9),
               T["geometry_msgs/msg/TwistStamped"](_header(store, t), _twist(store, t)))
        yield "/odom", "nav_msgs/msg/Odometry", ns, _odometry(store, t)
        yield ("/pose", "geometry_msgs/msg/PoseStamped", ns,
               T["geometry_msgs/msg/PoseStamped"](_header(store, t, "map"), _pose(store, t)))


def write_bag(path: Path, kind: str, messages) -> Path:
    """A bag of `kind` (ros1, sqlite3, mcap) at path with the messages, by rosbags' writers."""
    store = ROS1 if kind == "ros1" else ROS2
    if kind == "ros1":
        writer = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
    connections = {}
    with writer:
        for topic, msgtype, ns, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            data = (store.serialize_ros1 if kind == "ros1" else store.serialize_cdr)(msg, msgtype)
            writer.write(connections[topic], ns, data)
    return path


def bag_name(kind: str) -> str:
    return "seed.bag" if kind == "ros1" else f"seed_{kind}"


@pytest.fixture(scope="module")
def seed_bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    return {kind: write_bag(folder / bag_name(kind), kind,
                            seed_messages(ROS1 if kind == "ros1" else ROS2)) for kind in FORMATS}


def chain(folder: Path, source: str, name="bagrun", stop_time=10.0, extra="") -> Path:
    """The seed's chain with `source` as the VelocitySource's spec (a mapping's body)."""
    text = (f"name: {name}\n"
            f"experiment: {{start_time: 0.0, stop_time: {stop_time}, step_size: 0.05}}\n"
            "parameters: {alpha: 0.7853981633974483, L: 0.16, W: 0.12, R: 0.06}\n"
            "components:\n"
            f"  source: {{fmu: VelocitySource, {source}}}\n"
            "  c2w: {fmu: Center2Wheel}\n  w2c: {fmu: Wheel2Center}\n  pose: {fmu: PoseIntegrator}\n"
            + CHAIN_CONNECTIONS + extra)
    return write_scenario(folder, name, text)


def source_table(graph, name="source") -> str:
    return next(c for c in graph.scenario.components if c.name == name).parameters["table"]


def end_point(path: Path) -> tuple[float, float]:
    graph = prepare(path)
    results = master.simulate(graph, graph.scenario.experiment)
    return results.final("pose.x"), results.final("pose.y")


@pytest.fixture(scope="module")
def expression_end(tmp_path_factory):
    folder = tmp_path_factory.mktemp("expr")
    return end_point(chain(folder, "parameters: {vx_expr: 'sin(t)', vy_expr: 'cos(t)', "
                                   "w_expr: '0'}", name="expr"))


# ------------------------------------------------------------------ bags in


@pytest.mark.parametrize("kind", FORMATS)
@pytest.mark.parametrize("topic", ["/cmd_vel", "/cmd_vel_stamped"])
def test_the_seed_commands_from_each_bag_format_end_on_the_spec_point(
        tmp_path, seed_bags, expression_end, kind, topic):
    """The 100 Hz commands, linearly interpolated, are off the formulas by at most
    dt^2/8 |v''| = 1.25e-5 m/s per channel: 1.25e-4 m over 10 s."""
    path = chain(tmp_path, f"table: {{file: {seed_bags[kind]}, topic: {topic}}}")
    x, y = end_point(path)
    print(f"{kind} {topic}: end ({x:.6f}, {y:.6f}), expressions ({expression_end[0]:.6f}, "
          f"{expression_end[1]:.6f})")
    assert math.dist((x, y), expression_end) < 1.25e-4
    assert (round(x, 3), round(y, 3)) == SEED_END


def test_stamped_commands_use_the_header_stamp_and_log_time_on_request(tmp_path, seed_bags):
    """The stamped topic is logged DELAY after its stamps: its table starts at the first stamp
    (0 s), and with `stamps: log` DELAY later."""
    bag = seed_bags["mcap"]
    graph = prepare(chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel_stamped, "
                                    "stamps: log}", stop_time=2.0))
    first = source_table(graph).splitlines()[1].split(",")
    assert float(first[0]) == pytest.approx(DELAY, abs=1e-9)
    graph = prepare(chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel_stamped}}",
                          name="header", stop_time=2.0))
    first = source_table(graph).splitlines()[1].split(",")
    assert float(first[0]) == pytest.approx(0.0, abs=1e-9)
