"""Imported by the recorder's fork server (its preload list): the server dies with the recorder.

multiprocessing's fork server has no hook but the modules it preloads. Importing this one in the
server (a ``python -c "from multiprocessing.forkserver import main; ..."`` process) makes it ask
for SIGKILL when the recorder ends (app/processes/lifetime.py), so that a recorder killed by SIGKILL
leaves no server behind; its workers, forked from the server, follow it the same way. Imported
anywhere else it does nothing.

In the server it also loads the type support of the contract's messages (nodes/interfaces.py
`load_type_supports`): each worker, forked from the server, then has them instead of loading
those of its 20-odd subscriptions itself, after `lubrig rig`'s start gate has opened.
"""

from __future__ import annotations

import contextlib
import sys

from lubrig_ros.app.processes.lifetime import die_with_parent

IN_FORK_SERVER = sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules

if IN_FORK_SERVER:
    die_with_parent()
    from lubrig_ros.nodes.interfaces import load_type_supports

    with contextlib.suppress(Exception):  # a head start only: a worker loads what it needs itself
        load_type_supports()
