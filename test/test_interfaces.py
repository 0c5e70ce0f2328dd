"""lubrig_interfaces: the messages built by `make setup` work with rclpy, DDS, rosbags and mcap.

Each message is built with distinctive values and must come back equal from rclpy's CDR round
trip; a RigStateBlock goes between two real processes over DDS and arrives equal, with the type
hash the rosidl generator computed; rosbags, given only the .msg files, computes the same RIHS01
type hashes and writes an MCAP file that `mcap` + `mcap-ros2-support` decode from the schema in
the file alone.
"""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64

from lubrig_ros.app.interface import cdr
from lubrig_ros.app.plant.output import BLOCK_FIELDS
from lubrig_ros.core.errors import InputError
from lubrig_ros.core.schema import SHADOW_FIELDS

pytestmark = pytest.mark.ros

try:
    import lubrig_interfaces.msg as msg
except ImportError as exc:  # loud, not skipped: `make test` builds it first (make setup)
    raise ImportError(f"lubrig_interfaces is not installed in {sys.prefix}: run make setup ({exc})") from exc

PACKAGE = "lubrig_interfaces"
MESSAGES = (
    "RigState",
    "RigStateBlock",
    "BandVelocityBlock",
    "WaveletFrame",
    "StabilityFlags",
    "FlowProgress",
    "ShadowBlock",
)
#: The replay's services (lubrig_interfaces/srv): rosbag2's player has the same two.
SERVICES = ("Seek", "SetRate")
SHARE = Path(sys.prefix) / "share" / PACKAGE / "msg"
N = 100  # samples in the test blocks


def _stamp(header_or_time, t: float) -> None:
    stamp = getattr(header_or_time, "stamp", header_or_time)
    stamp.sec = int(t)
    stamp.nanosec = round((t - int(t)) * 1e9)


def rig_state():
    m = msg.RigState()
    _stamp(m.header, 12.345)
    m.header.frame_id = "rig"
    m.sample_index = 12345
    m.segment = 2
    for i, name in enumerate(BLOCK_FIELDS):  # every sample field, then chosen values for some
        setattr(m, name, 1e-3 * (i + 1))
    m.displacement, m.velocity = 1.25e-6, -3.5e-5
    m.friction_coefficient, m.friction_force = 0.0712, 7.12e-3
    m.band_velocity, m.relative_velocity, m.belt_travel = 1e-4, 1.35e-4, 1.2345e-3
    return m


def rig_state_block(n: int = N):
    m = msg.RigStateBlock()
    _stamp(m.header, 2.5)
    m.sample_period = 1e-3
    m.first_sample_index = 2500
    m.segment = 1
    k = range(n)
    for j, name in enumerate(BLOCK_FIELDS):  # every sample field, then chosen values for some
        setattr(m, name, [1e-3 * (j + 1) + 1e-6 * i for i in k])
    m.displacement = [1e-6 * (i % 7 - 3) for i in k]
    m.velocity = [-2e-5 * (i % 5) for i in k]
    m.friction_coefficient = [0.07 + 1e-4 * i for i in k]
    m.friction_force = [1e-3 * (0.07 + 1e-4 * i) for i in k]
    m.band_velocity = [1e-4 + 1e-7 * i for i in k]
    m.relative_velocity = [1e-4 + 1e-7 * i + 2e-5 * (i % 5) for i in k]
    m.belt_travel = [2.5e-4 + 1e-7 * i for i in k]
    return m


def band_velocity_block():
    m = msg.BandVelocityBlock()
    _stamp(m.header, 0.1)
    m.sample_period = 1e-3
    m.first_sample_index = 100
    m.band_velocity = [1e-4 * (1 + 0.5 * (i % 10)) for i in range(N)]
    return m


def wavelet_frame(rows: int = 4, cols: int = 3):
    m = msg.WaveletFrame()
    _stamp(m.header, 3.002)
    m.frequency = [250.0 / 2**r for r in range(rows)]
    _stamp(m.start, 3.0)
    _stamp(m.end, 3.002)
    m.rows, m.cols = rows, cols
    m.power = [float(r * cols + c) + 0.5 for r in range(rows) for c in range(cols)]  # exact in float32
    return m


def stability_flags():
    m = msg.StabilityFlags()
    _stamp(m.header, 4.0)
    m.linear_zone = msg.StabilityFlags.ZONE_FALLING
    m.band_velocity, m.damping_ratio = 1e-4, 0.05
    m.critical_damping_ratio, m.effective_damping = 0.12, -0.14
    m.linear_stable = False
    m.oscillation = msg.StabilityFlags.OSCILLATION_GROWING
    m.oscillation_growing = True
    m.growth_rate, m.growth_fit_r2 = 0.8, 0.97
    m.sticking, m.stick_threshold, m.stick_share = True, 2e-5, 0.25
    m.stick_episodes, m.longest_stick = 3, 0.04
    m.resonance, m.resonance_harmonic = True, 2
    return m


def flow_progress():
    m = msg.FlowProgress()
    _stamp(m.header, 5.099)
    m.participant = "/lubrig/recorder"
    m.segment, m.samples = 3, 5100
    return m


def shadow_block():
    m = msg.ShadowBlock()
    _stamp(m.header, 6.02)
    m.sample_period, m.segment = 1e-3, 1
    m.sample_index = [6001, 6002, 6004]
    m.measured_displacement = [1.5e-6, 1.6e-6, 1.8e-6]
    m.simulated_displacement = [1.4e-6, 1.65e-6, 1.8e-6]
    m.band_velocity = [1e-4, 1e-4, 1.1e-4]
    m.residual = [1e-7, -5e-8, 0.0]
    m.residual_rms = [1e-7, 7.9e-8, 6.5e-8]
    m.measured_rejected, m.unpaired = 2, 1
    return m


BUILDERS = {
    "FlowProgress": flow_progress,
    "RigState": rig_state,
    "RigStateBlock": rig_state_block,
    "BandVelocityBlock": band_velocity_block,
    "WaveletFrame": wavelet_frame,
    "StabilityFlags": stability_flags,
    "ShadowBlock": shadow_block,
}


def test_every_message_is_generated_and_installed():
    for name in MESSAGES:
        assert hasattr(msg, name), name
        for ext in ("msg", "idl", "json"):
            assert (SHARE / f"{name}.{ext}").is_file(), f"{name}.{ext} not installed in {SHARE}"
    index = Path(sys.prefix) / "share" / "ament_index" / "resource_index"
    assert (index / "packages" / PACKAGE).is_file()
    interfaces = (index / "rosidl_interfaces" / PACKAGE).read_text().split()
    expected = [f"msg/{n}.{ext}" for n in MESSAGES for ext in ("idl", "msg")]
    expected += [f"srv/{n}.{ext}" for n in SERVICES for ext in ("idl", "srv")]
    assert sorted(interfaces) == sorted(expected)
    import lubrig_interfaces.srv as srv

    for name in SERVICES:
        assert hasattr(srv, name), name


@pytest.mark.parametrize("name", MESSAGES)
def test_cdr_round_trip_is_equal(name):
    original = BUILDERS[name]()
    assert original != getattr(msg, name)(), "the test message must differ from the default one"
    data = serialize_message(original)
    back = deserialize_message(data, getattr(msg, name))
    assert back == original  # (not byte-compared: rclpy leaves CDR padding bytes uninitialized)


def test_the_plant_s_hand_serialized_rig_state_is_what_rclpy_reads():
    original = rig_state()
    original.header.frame_id = ""  # the plant's states carry no frame
    encoder = cdr.StampedEncoder(msg.RigState.get_fields_and_field_types())
    values = tuple(getattr(original, name) for name in encoder.names)
    data = encoder.encode(original.header.stamp.sec, original.header.stamp.nanosec, values)
    assert len(data) == len(serialize_message(original))
    assert deserialize_message(data, msg.RigState) == original
    with pytest.raises(InputError, match="fixed-size scalar"):
        cdr.StampedEncoder(msg.RigStateBlock.get_fields_and_field_types())  # arrays: not for it
    with pytest.raises(InputError, match="Header"):
        cdr.StampedEncoder(Float64.get_fields_and_field_types())  # no header


def test_block_arrays_keep_float64_precision_and_length():
    block = deserialize_message(serialize_message(rig_state_block()), msg.RigStateBlock)
    expected = rig_state_block()
    for field in (
        "displacement",
        "velocity",
        "friction_coefficient",
        "friction_force",
        "band_velocity",
        "relative_velocity",
        "belt_travel",
    ):
        assert len(getattr(block, field)) == N
        assert list(getattr(block, field)) == list(getattr(expected, field))  # bit for bit


def test_constants_and_field_types_are_as_documented():
    flags = msg.StabilityFlags
    assert (flags.ZONE_UNKNOWN, flags.ZONE_JUNCTION, flags.ZONE_FALLING, flags.ZONE_VISCOUS) == (0, 1, 2, 3)
    assert flags.OSCILLATION_UNKNOWN == 0 and flags.OSCILLATION_GROWING == 3
    assert msg.WaveletFrame.get_fields_and_field_types()["power"] == "sequence<float>"
    assert msg.RigStateBlock.get_fields_and_field_types()["displacement"] == "sequence<double>"
    assert msg.RigState.get_fields_and_field_types()["sample_index"] == "uint64"


def rosidl_type_hash(name: str) -> str:
    """The RIHS01 hash rosidl computed at build time (installed type description)."""
    description = json.loads((SHARE / f"{name}.json").read_text())
    (entry,) = [h for h in description["type_hashes"] if h["type_name"] == f"{PACKAGE}/msg/{name}"]
    return entry["hash_string"]


def rosbags_typestore():
    """rosbags' Kilted type store with the .msg files of this repository registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    source = Path(__file__).resolve().parents[1] / PACKAGE / "msg"
    types = {}
    for name in MESSAGES:
        types.update(get_types_from_msg((source / f"{name}.msg").read_text(), f"{PACKAGE}/msg/{name}"))
    store.register(types)
    return store


def test_installed_msg_files_are_the_repository_ones():
    source = Path(__file__).resolve().parents[1] / PACKAGE / "msg"
    for name in MESSAGES:
        assert (SHARE / f"{name}.msg").read_text() == (source / f"{name}.msg").read_text(), (
            f"{name}.msg changed since the last build: run make setup"
        )


@pytest.mark.parametrize("name", MESSAGES)
def test_rosbags_type_hash_equals_rosidl(name):
    store = rosbags_typestore()
    assert rosidl_type_hash(name).startswith("RIHS01_")
    assert store.hash_rihs01(f"{PACKAGE}/msg/{name}") == rosidl_type_hash(name)


@pytest.mark.parametrize("name", MESSAGES)
def test_rosbags_decodes_rclpy_cdr(name):
    store = rosbags_typestore()
    original = BUILDERS[name]()
    decoded = store.deserialize_cdr(serialize_message(original), f"{PACKAGE}/msg/{name}")
    for field in original.get_fields_and_field_types():
        value, other = getattr(original, field), getattr(decoded, field)
        if field in ("header", "start", "end"):
            stamp = value.stamp if field == "header" else value
            other_stamp = other.stamp if field == "header" else other
            assert (other_stamp.sec, other_stamp.nanosec) == (stamp.sec, stamp.nanosec)
        elif isinstance(value, (int, float, bool)):
            assert other == value, field
        else:
            assert list(other) == list(value), field
    # rosbags' own CDR goes back into rclpy equal as well
    cdr = bytes(store.serialize_cdr(decoded, f"{PACKAGE}/msg/{name}"))
    assert deserialize_message(cdr, getattr(msg, name)) == original


# Two processes over DDS: a publisher (transient local, so start order does not matter) and a
# raw subscriber that writes the bytes it received and the publisher's type hash from the graph.
PUBLISHER = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message
    from lubrig_interfaces.msg import RigStateBlock

    block = deserialize_message(open(sys.argv[1], "rb").read(), RigStateBlock)
    rclpy.init()
    node = rclpy.create_node("test_block_publisher")
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_publisher(RigStateBlock, "/lubrig_test/state_block", qos).publish(block)
    print("published", flush=True)
    deadline = time.monotonic() + float(sys.argv[2])
    while rclpy.ok() and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    """
)
SUBSCRIBER = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from lubrig_interfaces.msg import RigStateBlock

    rclpy.init()
    node = rclpy.create_node("test_block_subscriber")
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    got = []
    node.create_subscription(RigStateBlock, "/lubrig_test/state_block", got.append, qos, raw=True)
    deadline = time.monotonic() + float(sys.argv[2])
    while not got and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if not got:
        sys.exit("no RigStateBlock received")
    open(sys.argv[1], "wb").write(got[0])
    infos = node.get_publishers_info_by_topic("/lubrig_test/state_block")
    print("type", infos[0].topic_type if infos else "")
    print("hash", infos[0].topic_type_hash if infos else "")
    """
)


def _ros_env() -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(100 + (os.getpid() * 7 + random.randrange(1000)) % 101)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    return env


def test_rig_state_block_between_two_processes_over_dds(tmp_path):
    original = rig_state_block()
    sent, received = tmp_path / "sent.cdr", tmp_path / "received.cdr"
    sent.write_bytes(serialize_message(original))
    env, timeout = _ros_env(), 90.0
    publisher = subprocess.Popen(
        [sys.executable, "-c", PUBLISHER, str(sent), str(timeout)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        result = subprocess.run(
            [sys.executable, "-c", SUBSCRIBER, str(received), str(timeout)],
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout + 30,
        )
    finally:
        publisher.kill()
        publisher_output = publisher.communicate(timeout=30)[0]
    assert result.returncode == 0, f"{result.stdout}{result.stderr}\npublisher: {publisher_output}"
    assert "published" in publisher_output
    block = deserialize_message(received.read_bytes(), msg.RigStateBlock)
    assert block == original
    lines = dict(line.split(" ", 1) for line in result.stdout.splitlines() if " " in line)
    assert lines["type"] == f"{PACKAGE}/msg/RigStateBlock"
    assert lines["hash"] == rosidl_type_hash("RigStateBlock")  # the hash DDS discovery carries


def test_mcap_from_rosbags_decodes_with_mcap_ros2_support_from_the_schema_alone(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = rosbags_typestore()
    original = rig_state_block()
    flags = stability_flags()
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/lubrig/state_block", f"{PACKAGE}/msg/RigStateBlock", typestore=store)
        writer.write(conn, 2_500_000_000, serialize_message(original))
        conn = writer.add_connection(
            "/lubrig/stability_flags", f"{PACKAGE}/msg/StabilityFlags", typestore=store
        )
        writer.write(conn, 4_000_000_000, serialize_message(flags))
    (path,) = bag.glob("*.mcap")
    with path.open("rb") as f:  # an independent reader: only what the file holds
        decoded = {
            channel.topic: (schema.name, schema.encoding, message.log_time, ros_msg)
            for schema, channel, message, ros_msg in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        }
    name, encoding, log_time, block = decoded["/lubrig/state_block"]
    assert (name, encoding, log_time) == (f"{PACKAGE}/msg/RigStateBlock", "ros2msg", 2_500_000_000)
    assert (block.header.stamp.sec, block.header.stamp.nanosec) == (2, 500_000_000)
    assert block.sample_period == original.sample_period
    assert block.first_sample_index == original.first_sample_index
    for field in (
        "displacement",
        "velocity",
        "friction_coefficient",
        "friction_force",
        "band_velocity",
        "relative_velocity",
        "belt_travel",
    ):
        assert list(getattr(block, field)) == list(getattr(original, field)), field
    name, _, _, got = decoded["/lubrig/stability_flags"]
    assert name == f"{PACKAGE}/msg/StabilityFlags"
    for field in flags.get_fields_and_field_types():
        if field != "header":
            assert getattr(got, field) == getattr(flags, field), field


SOURCE_MSG = Path(__file__).resolve().parents[1] / PACKAGE / "msg"


def _sample_lines(name: str) -> dict[str, tuple[str, str]]:
    """{field: (type, unit)} of the float64 fields of a .msg, its comments reading '# unit: ...'."""
    out = {}
    for line in (SOURCE_MSG / f"{name}.msg").read_text().splitlines():
        head, _, comment = line.partition("#")
        words = head.split()
        if len(words) == 2 and words[0] in ("float64", "float64[]"):
            out[words[1]] = (words[0], comment.strip().partition(":")[0])
    return out


def test_the_msg_files_carry_the_schema_s_sample_fields_in_order_with_their_units():
    from lubrig_ros.app.plant.output import BLOCK_FIELDS
    from lubrig_ros.core.schema import SAMPLE_FIELDS, SAMPLE_UNITS

    expected = {f.name: f.unit for f in SAMPLE_FIELDS}
    state = _sample_lines("RigState")
    assert {k: unit for k, (_, unit) in state.items()} == expected
    assert list(msg.RigState.get_fields_and_field_types()) == [
        "header",
        "sample_index",
        "segment",
        *BLOCK_FIELDS,
    ]
    block = _sample_lines("RigStateBlock")
    assert {k: (kind, unit) for k, (kind, unit) in block.items() if k != "sample_period"} == {
        **{name: ("float64[]", unit) for name, unit in expected.items()},
        "lateness": ("float64[]", SAMPLE_UNITS["lateness"]),
    }
    arrays = [
        k for k, kind in msg.RigStateBlock.get_fields_and_field_types().items() if kind.startswith("sequence")
    ]
    assert arrays == [*BLOCK_FIELDS, "lateness"]


def test_shadow_block_arrays_are_the_schema_s_shadow_fields():
    types = msg.ShadowBlock.get_fields_and_field_types()
    arrays = [name for name, kind in types.items() if kind == "sequence<double>"]
    assert arrays == list(SHADOW_FIELDS)
    assert types["sample_index"] == "sequence<uint64>"
