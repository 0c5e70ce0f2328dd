"""ROS-free application layer: the facts and sessions between core/ and the adapters.

Subpackages by purpose: `interface` (the ROS interface as data), `plant`, `analysis`, `recording`,
`view`, `processes`; beside them `selection`, `rundir`, `flow`, `belt_session`, `timing`
and `fileio` (docs/architecture.md, "app/ by purpose").
"""
