"""Imported by the recorder's fork server (its preload list): the server dies with the recorder.

multiprocessing's fork server has no hook but the modules it preloads. Importing this one in the
server (a ``python -c "from multiprocessing.forkserver import main; ..."`` process) makes it ask
for SIGKILL when the recorder ends (app/processes/lifetime.py), so that a recorder killed by SIGKILL
leaves no server behind; its workers, forked from the server, follow it the same way. Imported
anywhere else it does nothing.
"""

from __future__ import annotations

import sys

from lubrig_ros.app.processes.lifetime import die_with_parent

IN_FORK_SERVER = sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules

if IN_FORK_SERVER:
    die_with_parent()
