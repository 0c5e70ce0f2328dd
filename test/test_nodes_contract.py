"""Live nodes declare exactly the contract's parameters (app/contract.py), over real DDS."""

from __future__ import annotations

import pytest
from rcl_interfaces.srv import DescribeParameters, ListParameters
from test_nodes_support import Probe, Procs, new_domain

from lubrig_ros.app import contract

pytestmark = pytest.mark.ros
STANDARD = {"use_sim_time", "start_type_description_service"}  # rclpy's own


def test_nodes_declare_the_contract_parameters(tmp_path):
    domain = new_domain()
    probe = Probe(domain)
    procs = Procs(domain, tmp_path)
    try:
        for node in contract.NODE_PARAMETERS:
            procs.start(node, case=1)
        for node, specs in contract.NODE_PARAMETERS.items():
            listed = probe.call(ListParameters, f"/{node}/list_parameters", ListParameters.Request(), 30)
            names = set(listed.result.names) - STANDARD
            expected = {p.name for p in specs if "<" not in p.name}
            if node == "belt_drive":  # profile.<field>: one parameter per profile field (core)
                assert {n for n in names if n.startswith("profile.")} > {"profile.kind"}
                names = {n for n in names if not n.startswith("profile.") or n == "profile.kind"}
            assert names == expected, (node, sorted(names ^ expected))
            described = probe.call(
                DescribeParameters,
                f"/{node}/describe_parameters",
                DescribeParameters.Request(names=sorted(expected)),
            )
            for d in described.descriptors:
                if d.name.startswith("profile."):
                    continue  # declared with the core profile classes' own text (belt_drive)
                spec = contract.parameter(node, d.name)
                assert d.description.startswith(spec.description), (node, d.name)
                assert d.read_only == spec.read_only, (node, d.name)
    finally:
        codes = procs.stop()
        probe.close()
    assert all(code == 0 for code in codes.values()), codes
