"""The rig as processes on a host.

`rig_plan` (the launch plan both launchers run), `discovery` (where DDS traffic may go),
`lifetime` (helpers die with their parent), `ament_install` (the package in an ament prefix).
"""
