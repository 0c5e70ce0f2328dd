"""Reports of recorded runs: bag → Trajectory + RunConfig, study-style figures and a Markdown page.

Public API:

- :func:`trajectory_from_bag` — rebuild the RunConfig (stored run_config) and the Trajectory
  (plant topics) of a bag written by the recorder.
- :func:`open_bag` — read a bag once (lubrig_ros.bag.Bag) with the topics the report reads.
- :func:`write_report` — figures, summary.json (as `lubrig simulate` writes it, plus the
  "wavelet" section of `lubrig analyze`) and report.md into a directory.
"""

from lubrig_ros.report.frombag import ReportError, open_bag, trajectory_from_bag
from lubrig_ros.report.page import write_report

__all__ = ["ReportError", "open_bag", "trajectory_from_bag", "write_report"]
