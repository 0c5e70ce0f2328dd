"""Live nodes declare exactly the contract's parameters (app/contract.py), over real DDS."""

from __future__ import annotations

from rcl_interfaces.srv import DescribeParameters, ListParameters

from lubrig_ros.app import contract

STANDARD = {"use_sim_time", "start_type_description_service"}  # rclpy's own
NS = contract.DEFAULT_NAMESPACE  # the nodes' namespace when started without -r __ns:=...


def test_nodes_declare_the_contract_parameters(procs, probe):
    for node in contract.NODE_PARAMETERS:
        procs.node(node, case=1)
    for node, specs in contract.NODE_PARAMETERS.items():
        listed = probe.call(ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 120)
        names = set(listed.result.names) - STANDARD
        expected = {p.name for p in specs if "<" not in p.name}
        if node == "belt_drive":  # profile.<field>: one parameter per profile field (core)
            assert {n for n in names if n.startswith("profile.")} > {"profile.kind"}
            names = {n for n in names if not n.startswith("profile.") or n == "profile.kind"}
        assert names == expected, (node, sorted(names ^ expected))
        described = probe.call(
            DescribeParameters,
            f"{NS}/{node}/describe_parameters",
            DescribeParameters.Request(names=sorted(expected)),
        )
        for d in described.descriptors:
            if d.name.startswith("profile."):
                continue  # declared with the core profile classes' own text (belt_drive)
            spec = contract.parameter(node, d.name)
            assert d.description.startswith(spec.description), (node, d.name)
            assert d.read_only == spec.read_only, (node, d.name)
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
