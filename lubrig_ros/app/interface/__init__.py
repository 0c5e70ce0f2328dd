"""The rig's ROS interface as data (no ROS import).

`contract`: topics, services, QoS and node parameters (re-exported from `node_parameters`,
`profile_parameters`, `parameter_types`, `names`); `diagnostics`: what a node reports;
`cdr`: the CDR reads done by hand; `contract_docs`: the tables of README.md and docs/.
"""
