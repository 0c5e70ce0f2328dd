"""BagWriter.close never repairs behind the caller's back: repair is a tool the caller runs.

A real write failure: a child process whose file size is capped (RLIMIT_FSIZE, SIGXFSZ ignored,
so write() fails with EFBIG like a full disk) writes until BagWriter raises, lifts the cap (so a
repair inside close() would succeed and be seen), then closes.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from lubrig_ros.bag import BagError, check_bag, read_arrays, repair_bag

CHILD = textwrap.dedent(
    """
    import json, resource, signal, sys
    import numpy as np
    from lubrig_ros.bag import BagError, BagWriter
    from lubrig_ros.bag.layout import typestore
    hard = resource.getrlimit(resource.RLIMIT_FSIZE)[1]
    resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, hard))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    ts = typestore()
    f64 = ts.types["std_msgs/msg/Float64"]
    w = BagWriter(sys.argv[1], run_config="a: 1\\n")
    written, error = 0, None
    try:
        for k in range(200_000):
            data = ts.serialize_cdr(f64(float(k) + np.random.default_rng(k).random()), "std_msgs/msg/Float64")
            w.write("/lubrig/displacement", "std_msgs/msg/Float64", 1_000_000 * k, data)
            written += 1
            if k % 200 == 199:
                w.flush()
    except BagError as exc:
        error = str(exc)
    resource.setrlimit(resource.RLIMIT_FSIZE, (hard, hard))  # space again: a repair could succeed now
    w.close()
    print(json.dumps({"written": written, "error": error, "failed": bool(w.failed)}))
    """
)


def test_failed_writer_close_leaves_repair_to_the_caller(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    res = subprocess.run(
        [sys.executable, "-c", CHILD, str(bag)], capture_output=True, text=True, timeout=120, check=False
    )
    assert res.returncode == 0, res.stderr
    status = json.loads(res.stdout.strip().splitlines()[-1])
    assert status["failed"] and "File too large" in status["error"], status
    # close() only closed the file: no metadata.yaml, no summary — the bag is not finalized
    assert not (bag / "metadata.yaml").exists()
    with pytest.raises(BagError, match="repair"):
        check_bag(bag)
    report = repair_bag(bag)  # the caller's explicit step (`lubrig bag repair DIR`, the recorder)
    assert report.rewritten and not report.complete
    summary = check_bag(bag)
    assert summary.run_config == "a: 1\n"
    got = read_arrays(bag, ["/lubrig/displacement"])["/lubrig/displacement"]
    n = got.t.size
    assert 200 <= n <= status["written"] and n % 200 == 0  # whole flushed chunks, in order
    assert list(got.t) == sorted(got.t)
