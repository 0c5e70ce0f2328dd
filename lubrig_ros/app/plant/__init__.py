"""The plant's rules without ROS.

`session` (`PlantSession`) over `state`, one `ModeRules` per mode (`modes`, `wallclock`,
`shadow_rules`), `shadow` (pairing measured with simulated samples), `output`, `config`,
`diagnostics`.
"""
