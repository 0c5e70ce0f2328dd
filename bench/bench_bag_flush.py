"""Cost of the writer's flush bound: time per message and file size, bound on and off.

    .venv/bin/python bench/bench_bag_flush.py [--seconds 60] [--rate 1000] [--block 50] [--repeat 3]

Writes --seconds of rig time with BagWriter twice per layout, once with the default bound (a chunk
every 0.2 s of log time or 1000 messages) and once with only the 1 MiB chunk size (an
MCAP writer's own default), and prints the best of --repeat wall times per message, the
chunks written and the file size. Layouts: per sample (4 Float64 + JointState + Clock per sample,
the old sim layout and the realtime one) and blocks (one 7 x --block Float64MultiArray payload, a
RigStateBlock's size, plus a band block and /clock per block). No fsync (the recorder's wall-clock
--flush-interval adds one fsync per interval).
"""

from __future__ import annotations

import argparse
import math
import struct
import tempfile
import time
from pathlib import Path

import numpy as np

from lubrig_ros.bag import BagWriter
from lubrig_ros.bag.writer import serialize_string, typestore


def _messages(layout: str, seconds: float, rate: float, block: int) -> list[tuple[str, str, int, bytes]]:
    ts = typestore()
    js, hdr, stamp = (
        ts.types[n]
        for n in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    clock = ts.types["rosgraph_msgs/msg/Clock"]
    out: list[tuple[str, str, int, bytes]] = []
    n = int(seconds * rate)
    step = 1 if layout == "per-sample" else block
    for k in range(0, n, step):
        t = round(k * 1e9 / rate)
        sec, nsec = divmod(t, 10**9)
        out.append(
            (
                "/clock",
                "rosgraph_msgs/msg/Clock",
                t,
                bytes(ts.serialize_cdr(clock(stamp(sec, nsec)), "rosgraph_msgs/msg/Clock")),
            )
        )
        x = [1e-6 * math.sin(0.01 * (k + i)) for i in range(step)]
        if layout == "per-sample":
            for topic in ("displacement", "velocity", "friction_coefficient", "band_velocity"):
                out.append(
                    (
                        f"/lubrig/{topic}",
                        "std_msgs/msg/Float64",
                        t,
                        b"\x00\x01\x00\x00" + struct.pack("<d", x[0]),
                    )
                )
            one = np.array(x[:1])
            state = js(hdr(stamp(sec, nsec), ""), ["mass"], one, one, one)
            out.append(
                (
                    "/lubrig/state",
                    "sensor_msgs/msg/JointState",
                    t,
                    bytes(ts.serialize_cdr(state, "sensor_msgs/msg/JointState")),
                )
            )
        else:
            head = b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nsec) + b"\x01\x00\x00\x00\x00\x00\x00\x00"
            body = b"".join(struct.pack("<I", step) + struct.pack(f"<{step}d", *x) for _ in range(7))
            out.append(("/lubrig/state_block", "std_msgs/msg/Float64MultiArray", t, head + body))
            band = head + body[: 4 + 8 * step]
            out.append(("/lubrig/band_velocity_block", "std_msgs/msg/Float64MultiArray", t, band))
    return out


def _write(path: Path, messages: list, bounded: bool) -> tuple[float, int, int]:
    kwargs = {} if bounded else {"flush_period_ns": 2**62, "flush_messages": 2**62}
    t0 = time.perf_counter()
    w = BagWriter(path, run_config="a: 1\n", **kwargs)
    w.write("/lubrig/run_config", "std_msgs/msg/String", 0, serialize_string("a: 1\n"))
    for topic, msgtype, t, data in messages:
        w.write(topic, msgtype, t, data)
    w.close()
    return time.perf_counter() - t0, w.chunks_flushed, (path / f"{path.name}.mcap").stat().st_size


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--rate", type=float, default=1000.0)
    p.add_argument("--block", type=int, default=50)
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for layout in ("per-sample", "blocks"):
            messages = _messages(layout, args.seconds, args.rate, args.block)
            rows = {}
            for bounded in (False, True):
                best = None
                for r in range(args.repeat):
                    res = _write(Path(tmp) / f"{layout}-{bounded}-{r}", messages, bounded)
                    best = res if best is None or res[0] < best[0] else best
                rows[bounded] = best
            for bounded, (wall, chunks, size) in rows.items():
                name = "bound 0.2 s / 1000 msgs" if bounded else "1 MiB chunks only"
                per_msg, per_s = wall * 1e6 / len(messages), wall / args.seconds * 1e3
                print(
                    f"{layout:10s} {name:24s} {len(messages):7d} msgs  {per_msg:6.2f} us/msg  "
                    f"{per_s:6.2f} ms per rig s  {chunks:5d} chunks  {size / 1e6:7.3f} MB"
                )
            extra = (rows[True][0] - rows[False][0]) / args.seconds
            print(
                f"{layout:10s} flush bound costs {extra * 1e3:+.2f} ms of wall time per rig second, "
                f"file {rows[True][2] / rows[False][2]:.2f} x"
            )


if __name__ == "__main__":
    main()
