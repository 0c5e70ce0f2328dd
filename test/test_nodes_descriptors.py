"""Every node parameter's range from the contract is in its ParameterDescriptor (issue 11).

`ros2 param describe` reads DescribeParameters; a separate process here does the same against
real node processes: the contract's bounds are the descriptor's floating_point_range /
integer_range, read-only and description match, and the valid values are stated. Values outside
are refused at start with the contract's message and at run time with a reason naming the
parameter, the value and the range.
"""

from __future__ import annotations

import math

from lubrig_testkit.harness import wait_until
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import DescribeParameters

from lubrig_ros.app.interface import contract
from lubrig_ros.app.processes.rig_plan import READY_LINES

NS = contract.DEFAULT_NAMESPACE


def _check_descriptor(node: str, d, spec: contract.NodeParameter) -> None:
    assert d.description.startswith(spec.description), (node, d.name)
    assert d.read_only == spec.read_only, (node, d.name)
    assert d.additional_constraints == f"valid: {spec.expected()}", (node, d.name)
    bounded = spec.low is not None or spec.high is not None
    if spec.type == "double" and bounded:
        (r,) = d.floating_point_range
        assert r.from_value == (-math.inf if spec.low is None else spec.low), (node, d.name)
        assert r.to_value == (math.inf if spec.high is None else spec.high), (node, d.name)
        assert not d.integer_range
    elif spec.type == "integer" and bounded:
        (r,) = d.integer_range
        assert r.from_value == (-(2**63) if spec.low is None else spec.low), (node, d.name)
        assert r.to_value == (2**63 - 1 if spec.high is None else spec.high), (node, d.name)
    else:
        assert not d.floating_point_range and not d.integer_range, (node, d.name)
    expected_type = {
        "double": ParameterType.PARAMETER_DOUBLE,
        "integer": ParameterType.PARAMETER_INTEGER,
        "string": ParameterType.PARAMETER_STRING,
        "bool": ParameterType.PARAMETER_BOOL,
        "string_array": ParameterType.PARAMETER_STRING_ARRAY,
    }
    assert d.type == expected_type[spec.type], (node, d.name, d.type)


def test_descriptors_hold_the_contract_ranges_and_runtime_updates_are_checked(procs, probe):
    nodes = {node: procs.node(node, case=1) for node in contract.NODE_PARAMETERS}
    for node, proc in nodes.items():  # each built and spinning (its start line), or its log
        wait_until(lambda p=proc, n=node: READY_LINES[n] in p.errors(), 180, f"{node} up", alive=(proc,))
    bounded = 0
    for node, specs in contract.NODE_PARAMETERS.items():
        # profile.*: declared from the core profile registry with its own text (belt_drive)
        names = sorted(p.name for p in specs if not p.name.startswith("profile."))
        try:  # idempotent: resent if a response is dropped (Probe.call)
            described = probe.call(
                DescribeParameters,
                f"{NS}/{node}/describe_parameters",
                DescribeParameters.Request(names=names),
                60,
                resend=5.0,
            )
        except AssertionError as exc:
            raise AssertionError(f"{exc}\n{procs.logs()}") from None
        assert [d.name for d in described.descriptors] == names
        for d in described.descriptors:
            spec = contract.parameter(node, d.name)
            _check_descriptor(node, d, spec)
            bounded += spec.low is not None or spec.high is not None
    assert bounded >= 15  # the ranges really are there (not a vacuous loop)

    # run time: rclpy refuses outside the descriptor's range first; the reason still names
    # the parameter, the bad value and the valid range
    result = probe.set_parameter("lubrig/plant", "rtol", 1.0)
    assert not result.successful
    assert "rtol" in result.reason and "1.0" in result.reason and "0.01" in result.reason, result.reason
    result = probe.set_parameter("lubrig/plant", "rtol", math.nan)
    assert not result.successful and "rtol" in result.reason and "nan" in result.reason
    # what the descriptor cannot hold (the choices of a string) is the contract's own message
    result = probe.set_parameter("lubrig/plant", "convention", "sideways")
    assert not result.successful
    assert "convention='sideways' is not valid; expected one of" in result.reason, result.reason
    assert probe.set_parameter("lubrig/plant", "rtol", 1e-9).successful  # in range: accepted
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
