"""Live nodes declare exactly the contract's parameters (app/interface/contract.py), over real DDS."""

from __future__ import annotations

from rcl_interfaces.srv import DescribeParameters, ListParameters

from lubrig_ros.app.interface import contract

STANDARD = {"use_sim_time", "start_type_description_service"}  # rclpy's own
NS = contract.DEFAULT_NAMESPACE  # the nodes' namespace when started without -r __ns:=...


def test_nodes_declare_the_contract_parameters(procs, probe):
    for node in contract.NODE_PARAMETERS:
        procs.node(node, case=1)
    for node, specs in contract.NODE_PARAMETERS.items():
        listed = probe.call(ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 120)
        names = set(listed.result.names) - STANDARD
        expected = {p.name for p in specs if "<" not in p.name}
        assert names == expected, (node, sorted(names ^ expected))
        described = probe.call(
            DescribeParameters,
            f"{NS}/{node}/describe_parameters",
            DescribeParameters.Request(names=sorted(expected)),
        )
        for d in described.descriptors:
            if d.name == "profile.kind":
                continue  # described with the registered kinds (core.profiles), extensions included
            spec = contract.parameter(node, d.name)
            assert d.description.startswith(spec.description), (node, d.name)
            assert d.read_only == spec.read_only, (node, d.name)
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
