"""ROS bags in and out (issue 32): real bags written here with rosbags' writers (ROS 1 .bag,
ROS 2 sqlite3, ROS 2 MCAP) holding the seed's commands, run as table sources; the run written
as an MCAP bag and read back with rosbags and with the `mcap` reader; each bad bag.

Reference values: the spec's end point of the seed, (1.839, -0.544) (docs/spec.md, The
original study), its closed form x = 1 - cos t, y = sin t, and the same scenario driven by the
expressions; the frame mapping of docs/conventions.md written out by hand here (ROS linear.x =
our vy, linear.y = -our vx; a point (x, y) of ours is ROS's (y, -x)).
"""
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from helpers import CHAIN_CONNECTIONS, LOOP_CONNECTIONS, run_main, write_scenario
from mecanum_fmu import cli, master
from mecanum_fmu.report.against_recorded import compare
from mecanum_fmu.runner import prepare

from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_typestore

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


@pytest.fixture(scope="module")
def csv_end(tmp_path_factory):
    """The same 100 Hz commands as a ROS export in CSV (docs/closed-loop.md, Logs as they
    come), read by the CSV rules."""
    folder = tmp_path_factory.mktemp("csv")
    rows = "".join(f"{i / RATE!r},{math.cos(i / RATE)!r},{-math.sin(i / RATE)!r},0.0\n"
                   for i in range(10 * RATE + 1))
    (folder / "seed.csv").write_text("time,linear.x,linear.y,angular.z\n" + rows)
    return end_point(chain(folder, "table: {file: seed.csv, columns: {vx: -linear.y, "
                                   "vy: linear.x, w: angular.z}}", name="csv"))


# ------------------------------------------------------------------ bags in


@pytest.mark.parametrize("kind", FORMATS)
@pytest.mark.parametrize("topic", ["/cmd_vel", "/cmd_vel_stamped"])
def test_the_seed_commands_from_each_bag_format_end_on_the_spec_point(
        tmp_path, seed_bags, expression_end, csv_end, kind, topic):
    """The bag's table is the CSV export's, row for row: the same run. The 100 Hz commands,
    linearly interpolated, are off the formulas by at most dt^2/8 |v''| = 1.25e-5 m/s per
    channel: 1.25e-4 m over 10 s."""
    path = chain(tmp_path, f"table: {{file: {seed_bags[kind]}, topic: {topic}}}")
    x, y = end_point(path)
    print(f"{kind} {topic}: end ({x!r}, {y!r}), CSV ({csv_end[0]!r}, {csv_end[1]!r}), "
          f"expressions ({expression_end[0]!r}, {expression_end[1]!r})")
    assert math.dist((x, y), csv_end) < 1e-12
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


# ------------------------------------------------------------------ bad bags


def bad_bag_lines(capsys, path: Path) -> list[str]:
    """The problem lines of `validate` (exit 2, no traceback)."""
    code, _, err = run_main(capsys, "validate", path)
    assert code == 2, err
    assert "Traceback" not in err
    print(err)                          # -s shows the lines as a user sees them
    return [line.strip() for line in err.splitlines()[1:] if line.strip()]


def _back_in_time(store):
    T = store.types
    for i, t in enumerate((0.0, 0.1, 0.2, 0.15, 0.3)):
        yield ("/cmd_vel", "geometry_msgs/msg/TwistStamped", i * 10**8,
               T["geometry_msgs/msg/TwistStamped"](_header(store, t), _twist(store, t)))


@pytest.mark.parametrize("kind", FORMATS)
def test_a_missing_topic_lists_the_topics_there(tmp_path, capsys, seed_bags, kind):
    lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {seed_bags[kind]}, "
                                                   "topic: /cmd_vel_nav}"))
    assert len(lines) == 1, lines
    assert str(seed_bags[kind]) in lines[0] and "topic /cmd_vel_nav" in lines[0]
    for topic, msgtype in (("/cmd_vel", "Twist"), ("/odom", "Odometry"),
                           ("/pose", "PoseStamped")):
        assert f"{topic} (geometry_msgs/msg/{msgtype})" in lines[0] or \
            f"{topic} (nav_msgs/msg/{msgtype})" in lines[0]


def test_a_topic_of_another_type_names_the_types_wanted(tmp_path, capsys, seed_bags):
    lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {seed_bags['sqlite3']}, "
                                                   "topic: /odom}"))
    assert len(lines) == 1, lines
    assert "/odom holds nav_msgs/msg/Odometry" in lines[0]
    assert "geometry_msgs/msg/Twist or geometry_msgs/msg/TwistStamped" in lines[0]


@pytest.mark.parametrize("kind", FORMATS)
def test_stamps_that_go_back_are_named_at_their_message(tmp_path, capsys, kind):
    store = ROS1 if kind == "ros1" else ROS2
    bag = write_bag(tmp_path / bag_name(kind), kind, _back_in_time(store))
    lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel}}"))
    assert len(lines) == 1, lines
    assert "go back or repeat at message 4 (0.15 s after 0.2 s; 1 such" in lines[0]
    assert "stamps: log" in lines[0]


@pytest.mark.parametrize("kind", FORMATS)
def test_a_topic_without_messages_is_an_empty_bag(tmp_path, capsys, kind):
    bag = write_bag(tmp_path / bag_name(kind), kind, [])
    store = ROS1 if kind == "ros1" else ROS2
    shutil.rmtree(bag) if bag.is_dir() else bag.unlink()
    writer = Writer1(bag) if kind == "ros1" else Writer2(
        bag, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap"
        else StoragePlugin.SQLITE3)
    with writer:
        writer.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=store)
    lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel}}"))
    assert len(lines) == 1, lines
    assert "has no messages on /cmd_vel" in lines[0] and str(bag) in lines[0]


def _storage_file(bag: Path) -> Path:
    return bag if bag.is_file() else next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))


@pytest.mark.parametrize("kind", FORMATS)
def test_a_truncated_bag_says_so(tmp_path, capsys, kind):
    store = ROS1 if kind == "ros1" else ROS2
    bag = write_bag(tmp_path / bag_name(kind), kind, seed_messages(store, seconds=1.0))
    data = _storage_file(bag)
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])
    lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel}}"))
    assert len(lines) == 1, lines
    assert "damaged or truncated" in lines[0] and str(bag) in lines[0]


def test_a_folder_without_metadata_yaml_names_the_fix(tmp_path, capsys, seed_bags):
    bag = shutil.copytree(seed_bags["mcap"], tmp_path / "copied")
    (bag / "metadata.yaml").unlink()
    for file in (bag, _storage_file(bag)):          # the folder, or the .mcap inside it
        lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: {file}, "
                                                       "topic: /cmd_vel}"))
        assert len(lines) == 1, lines
        assert "has no metadata.yaml" in lines[0] and "ros2 bag reindex" in lines[0]


def test_every_bad_bag_of_a_scenario_at_once(tmp_path, capsys, seed_bags):
    """Two sources, two bad bags: both lines, and the scenario's own problem beside them."""
    extra = ("  other: {fmu: VelocitySource, table: {file: nowhere, topic: /cmd_vel}}\n"
             "  third: {fmu: VelocitySource, table: {file: x.bag, topic: cmd_vel}}\n")
    path = chain(tmp_path, f"table: {{file: {seed_bags['ros1']}, topic: /odom}}")
    text = path.read_text().replace("connections:", extra.rstrip("\n") + "\nconnections:", 1)
    path.write_text(text)
    lines = bad_bag_lines(capsys, path)
    assert any("/odom holds nav_msgs/msg/Odometry" in line for line in lines), lines
    assert any("nowhere" in line and "not found" in line for line in lines), lines
    assert any("components.third.table.topic" in line for line in lines), lines


# ------------------------------------------------------------------ a recorded path


FOLLOWER = """\
name: {name}
experiment: {{start_time: 0.0, stop_time: 6.0, step_size: 0.05}}
parameters: {{alpha: 0.7853981633974483, L: 0.16, W: 0.12, R: 0.06}}
components:
  follower: {{fmu: PathFollower, {spec}}}
  c2w: {{fmu: Center2Wheel}}
  w2c: {{fmu: Wheel2Center}}
  pose: {{fmu: PoseIntegrator, parameters: {{x0: 0.2, y0: -0.15, theta0: 0.3}}}}
""" + LOOP_CONNECTIONS


@pytest.mark.parametrize("kind", FORMATS)
@pytest.mark.parametrize("topic", ["/odom", "/pose"])
def test_a_recorded_path_from_a_bag_is_the_closed_form_in_our_frame(tmp_path, seed_bags,
                                                                       kind, topic):
    spec = f"table: {{file: {seed_bags[kind]}, topic: {topic}}}"
    graph = prepare(write_scenario(tmp_path, "follow", FOLLOWER.format(name="follow", spec=spec)))
    header, *rows = source_table(graph, "follower").splitlines()
    assert header == "time,x,y,theta"
    t, x, y, theta = np.array([[float(v) for v in row.split(",")] for row in rows]).T
    assert len(t) == 10 * RATE + 1
    assert np.abs(x - (1 - np.cos(t))).max() < 1e-12 and np.abs(y - np.sin(t)).max() < 1e-12
    assert np.abs(theta).max() < 1e-12


def test_a_follower_on_a_bag_path_ends_where_it_does_on_the_csv_path(tmp_path, seed_bags):
    """The PathFollower on /odom and on the closed form x = 1 - cos t, y = sin t written here
    as a CSV path at the same 100 Hz: the same run (to the bag's float64 round trip)."""
    t = np.arange(10 * RATE + 1) / RATE
    rows = "".join(f"{a!r},{b!r},{c!r},0.0\n" for a, b, c in zip(t.tolist(), (1 - np.cos(t)).tolist(), np.sin(t).tolist()))
    (tmp_path / "path.csv").write_text("time,x,y,theta\n" + rows)
    ends = []
    for name, spec in (("bag", f"table: {{file: {seed_bags['mcap']}, topic: /odom}}"),
                       ("csv", "table: {file: path.csv}")):
        graph = prepare(write_scenario(tmp_path, name, FOLLOWER.format(name=name, spec=spec)))
        results = master.simulate(graph, graph.scenario.experiment)
        ends.append((results.final("pose.x"), results.final("pose.y")))
    print(f"follower on /odom: {ends[0]}, on the CSV path: {ends[1]}")
    assert math.dist(*ends) < 1e-9


# ------------------------------------------------------------------ bags out


@pytest.fixture(scope="module")
def written_bag(tmp_path_factory, seed_bags):
    """`run --bag` of the seed's chain driven by the ROS 1 bag's /cmd_vel."""
    folder = tmp_path_factory.mktemp("out")
    path = chain(folder, f"table: {{file: {seed_bags['ros1']}, topic: /cmd_vel}}")
    assert cli.main(["run", str(path), "--out", str(folder / "run"), "--no-plots", "--bag",
                     "--quiet"]) == 0
    header = (folder / "run" / "results.csv").open().readline().strip().split(",")
    data = np.loadtxt(folder / "run" / "results.csv", delimiter=",", skiprows=1)
    return folder / "run", {name: data[:, i] for i, name in enumerate(header)}


def test_the_written_bag_is_a_ros2_mcap_bag_rosbags_reads(written_bag):
    from rosbags.highlevel import AnyReader
    out, rows = written_bag
    assert sorted(p.name for p in (out / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]
    steps = len(rows["time"])
    with AnyReader([out / "bag"], default_typestore=ROS2) as reader:
        assert {t: (i.msgtype, i.msgcount) for t, i in reader.topics.items()} == {
            "/pose/odom": ("nav_msgs/msg/Odometry", steps), "/tf": ("tf2_msgs/msg/TFMessage", steps),
            "/pose/cmd_vel": ("geometry_msgs/msg/TwistStamped", steps)}
        last = {}
        for connection, ns, data in reader.messages():
            last[connection.topic] = (ns, reader.deserialize(data, connection.msgtype))
    ns, odom = last["/pose/odom"]
    assert ns == round(10.0 * 1e9) and odom.header.stamp.sec == 10
    # ours (x, y) is ROS's (y, -x): the end point (1.839, -0.544) is ROS (-0.544, -1.839)
    assert odom.pose.pose.position.x == pytest.approx(rows["pose.y"][-1], abs=1e-12)
    assert odom.pose.pose.position.y == pytest.approx(-rows["pose.x"][-1], abs=1e-12)
    assert (round(-odom.pose.pose.position.y, 3), round(odom.pose.pose.position.x, 3)) == SEED_END
    frame = last["/tf"][1].transforms[0]
    assert (frame.header.frame_id, frame.child_frame_id) == ("world", "pose/base_link")
    assert frame.transform.translation.x == odom.pose.pose.position.x
    cmd = last["/pose/cmd_vel"][1].twist     # the seed at 10 s: linear.x = cos 10, y = -sin 10
    assert cmd.linear.x == pytest.approx(math.cos(10.0), abs=1e-6)
    assert cmd.linear.y == pytest.approx(-math.sin(10.0), abs=1e-6)


def test_the_written_bag_opens_in_the_mcap_reader(written_bag):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    out, rows = written_bag
    with open(out / "bag" / "bag.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        xs = [(m.log_time, msg.pose.pose.position.y) for _, _, m, msg in
              reader.iter_decoded_messages(topics=["/pose/odom"])]
    assert schemas == {"/pose/odom": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
                       "/pose/cmd_vel": "geometry_msgs/msg/TwistStamped"}
    assert summary.statistics.message_count == 3 * len(rows["time"])
    assert [t for t, _ in xs] == [round(t * 1e9) for t in rows["time"]]
    assert np.array([y for _, y in xs]) == pytest.approx(-rows["pose.x"], abs=1e-12)


def test_the_written_bag_reads_back_as_a_recorded_path(tmp_path, written_bag):
    """The run's own /pose/odom as a PathFollower's table: our frame again, row for row."""
    out, rows = written_bag
    spec = f"table: {{file: {out / 'bag'}, topic: /pose/odom}}"
    graph = prepare(write_scenario(tmp_path, "back", FOLLOWER.format(name="back", spec=spec)))
    t, x, y, _ = np.array([[float(v) for v in row.split(",")]
                           for row in source_table(graph, "follower").splitlines()[1:]]).T
    assert np.abs(x - rows["pose.x"]).max() < 1e-12 and np.abs(y - rows["pose.y"]).max() < 1e-12


def test_a_failed_run_leaves_no_bag_and_removes_the_old_one(tmp_path, capsys, written_bag):
    """A run that stops at t = 1 s (sqrt of a negative number) keeps its rows, not a bag: the
    earlier run's bag/ in the same folder is gone too."""
    out = tmp_path / "run"
    shutil.copytree(written_bag[0], out)
    path = chain(tmp_path, "parameters: {vx_expr: 'sqrt(1 - t)', vy_expr: 'cos(t)', "
                           "w_expr: '0'}")
    code, _, err = run_main(capsys, "run", path, "--out", out, "--no-plots", "--bag")
    assert code == 1 and "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "summary.json"]


def test_a_folder_in_the_way_of_the_bag_is_bad_input(tmp_path, capsys, seed_bags):
    out = tmp_path / "run"
    (out / "bag").mkdir(parents=True)
    (out / "bag" / "mine.txt").write_text("a user's own file")
    path = chain(tmp_path, f"table: {{file: {seed_bags['mcap']}, topic: /cmd_vel}}")
    code, _, err = run_main(capsys, "run", path, "--out", out, "--no-plots", "--bag")
    assert code == 2 and "is in the way" in err and "Traceback" not in err
    assert (out / "bag" / "mine.txt").read_text() == "a user's own file"


# ------------------------------------------------------------------ held against a recording


def _shifted_odometry(store, ahead=0.1, yaw=0.2):
    """The seed's /odom moved `ahead` along ROS x (our +Y) and turned by `yaw`."""
    for topic, msgtype, ns, msg in seed_messages(store):
        if topic == "/odom":
            msg = _odometry(store, ns / 1e9, yaw)
            msg.pose.pose.position.x += ahead
            yield topic, msgtype, ns, msg


def test_a_run_held_against_its_own_recorded_odometry(tmp_path, seed_bags):
    """Driven by /cmd_vel and held against /odom of the same bag (the closed form): the error
    is the run's own (3.7e-6 m at the end, docs/masters.md) plus reading the 100 Hz recording
    linearly, dt^2/8 = 1.25e-5 m: under 1e-4 m everywhere."""
    bag = seed_bags["sqlite3"]
    path = chain(tmp_path, f"table: {{file: {bag}, topic: /cmd_vel}}",
                 extra=f"recorded:\n  pose: {{file: {bag}, topic: /odom}}\n")
    assert cli.main(["run", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    against = summary["against_recorded"]["pose"]
    print(f"against /odom: {against}")
    assert against["samples"] == 201 and (against["from"], against["to"]) == (0.0, 10.0)
    assert against["position_error_m"]["max"] < 1e-4
    assert against["heading_error_rad"]["max"] < 1e-12
    assert "recorded.png" in summary["files"] and (tmp_path / "run" / "recorded.png").stat().st_size
    # the dashboard holds the comparison too, as its own two panels beside recorded.png
    for name in ("recorded_path.png", "recorded_error.png"):
        assert name in summary["files"] and (tmp_path / "run" / name).stat().st_size > 1000


def test_a_recording_off_by_a_known_offset_shows_that_offset(tmp_path):
    """/odom 0.1 m ahead (ROS x: our +Y) and turned 0.2 rad: the error is 0.1 m and
    -0.2 rad (simulated minus recorded) to the run's own error."""
    bag = write_bag(tmp_path / "off", "mcap", _shifted_odometry(ROS2))
    path = chain(tmp_path, "parameters: {vx_expr: 'sin(t)', vy_expr: 'cos(t)', w_expr: '0'}",
                 extra=f"recorded:\n  pose: {{file: {bag}, topic: /odom}}\n")
    graph = prepare(path)
    results = master.simulate(graph, graph.scenario.experiment)
    against = compare(results, graph.scenario.recorded)["pose"]
    for figure in ("max", "rms", "end"):
        assert against["position_error_m"][figure] == pytest.approx(0.1, abs=1e-4)
        assert abs(against["heading_error_rad"][figure]) == pytest.approx(0.2, abs=1e-9)
    assert against["heading_error_rad"]["end"] == pytest.approx(-0.2, abs=1e-9)


def test_a_recording_for_no_pose_is_bad_input(tmp_path, capsys, seed_bags):
    path = chain(tmp_path, "parameters: {vx_expr: 'sin(t)', vy_expr: 'cos(t)', w_expr: '0'}",
                 extra=f"recorded:\n  car: {{file: {seed_bags['mcap']}, topic: /odom}}\n"
                       f"  pose: {{file: {seed_bags['mcap']}, topic: /cmd_vel}}\n")
    lines = bad_bag_lines(capsys, path)
    assert len(lines) == 2, lines
    assert any("recorded.car: names no PoseIntegrator (the scenario's: pose)" in line
               for line in lines)
    assert any("/cmd_vel holds geometry_msgs/msg/Twist; this table reads nav_msgs/msg/Odometry"
               in line for line in lines)


def test_bag_start_keeps_the_topics_of_a_bag_aligned(tmp_path):
    """Wall-clock stamps (1.7e9 s): `start: bag_start` puts the bag's first message at the
    start_time for every topic; /late starts 2 s after it, so its table starts at 2 s."""
    T = ROS2.types
    epoch = 1_700_000_000 * 10**9

    def messages():
        for i in range(5):
            yield "/cmd_vel", "geometry_msgs/msg/Twist", epoch + i * 10**9, _twist(ROS2, i)
        for i in range(3):
            yield ("/late", "geometry_msgs/msg/TwistStamped", epoch + (2 + i) * 10**9,
                   T["geometry_msgs/msg/TwistStamped"](_header(ROS2, 1.7e9 + 2 + i),
                                                       _twist(ROS2, i)))
    bag = write_bag(tmp_path / "wall", "mcap", messages())
    times = {}
    for topic in ("/cmd_vel", "/late"):
        graph = prepare(chain(tmp_path, f"table: {{file: {bag}, topic: {topic}, "
                                        "start: bag_start, offset: 0.5}", stop_time=2.0))
        times[topic] = [float(r.split(",")[0]) for r in source_table(graph).splitlines()[1:]]
    assert times == {"/cmd_vel": [0.5, 1.5, 2.5, 3.5, 4.5], "/late": [2.5, 3.5, 4.5]}


def test_the_bag_keys_on_a_csv_file_are_named(tmp_path, capsys):
    (tmp_path / "log.csv").write_text("time,vx,vy,w\n0,0,0,0\n1,0,0,0\n")
    for key, value in (("start", "bag_start"), ("stamps", "log")):
        lines = bad_bag_lines(capsys, chain(tmp_path, f"table: {{file: log.csv, {key}: {value}}}"))
        assert len(lines) == 1 and f"components.source.table.{key}: {value} is for a bag" \
            in lines[0], lines


def test_a_recorded_heading_that_crosses_pi_stays_continuous(tmp_path):
    """yaw = 0.5 t for 10 s: the quaternions wrap at pi (t = 2 pi), the table does not."""
    T = ROS2.types

    def messages():
        for i in range(101):
            t = i / 10
            yield ("/pose", "geometry_msgs/msg/PoseStamped", round(t * 1e9),
                   T["geometry_msgs/msg/PoseStamped"](_header(ROS2, t), _pose(ROS2, t, 0.5 * t)))
    bag = write_bag(tmp_path / "turning", "mcap", messages())
    spec = f"table: {{file: {bag}, topic: /pose}}"
    graph = prepare(write_scenario(tmp_path, "turn", FOLLOWER.format(name="turn", spec=spec)))
    t, _, _, theta = np.array([[float(v) for v in row.split(",")]
                               for row in source_table(graph, "follower").splitlines()[1:]]).T
    assert np.abs(theta - 0.5 * t).max() < 1e-12
