"""The topic/service/parameter contract (app/interface/contract.py): names, the one namespace validator,
and the documentation and config/nodes.yaml that must agree with it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import yaml

from lubrig_ros.app.interface import contract, contract_docs
from lubrig_ros.core.params import ParameterError

VALID = ["/lubrig", "/", "/rig_2", "/a/b2", "/_", "/A/_x", "/" + "a" * 244]
INVALID = [
    "",
    "lubrig",
    "/rig-2",
    "/lubrig/",
    "/a//b",
    "/2rig",
    "/a/2b",
    "/a b",
    "/~a",
    "/ä",
    "/a.b",
    "/" + "a" * 245,
]


@pytest.mark.parametrize("namespace", VALID)
def test_valid_namespaces(namespace):
    assert contract.validate_namespace(namespace) == namespace


@pytest.mark.parametrize("namespace", INVALID)
def test_invalid_namespaces_name_the_value_and_the_rule(namespace):
    with pytest.raises(ParameterError) as err:
        contract.validate_namespace(namespace, "topic_namespace")
    text = str(err.value)
    assert f"topic_namespace={namespace!r} is not valid" in text
    assert "expected an absolute ROS name" in text


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is None, reason="rclpy not installed")
@pytest.mark.parametrize("namespace", VALID + INVALID)
def test_validator_agrees_with_rclpy(namespace):
    """Our rules are ROS 2's: rclpy's own validator gives the same verdict on every case."""
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.validate_namespace import validate_namespace

    try:
        validate_namespace(namespace)
        ros_ok = True
    except InvalidNamespaceException:
        ros_ok = False
    ours_ok = True
    try:
        contract.validate_namespace(namespace)
    except ParameterError:
        ours_ok = False
    assert ours_ok == ros_ok, namespace


def test_resolve_relative_and_absolute_names():
    assert contract.resolve("/lubrig", "band_velocity") == "/lubrig/band_velocity"
    assert contract.resolve("/rig_2", "plant/reset") == "/rig_2/plant/reset"
    assert contract.resolve("/", "state") == "/state"
    assert contract.resolve("/lubrig", "/clock") == "/clock"
    with pytest.raises(ParameterError, match="rig-2"):
        contract.resolve("/rig-2", "state")
    with pytest.raises(ParameterError, match="2x"):
        contract.resolve("/lubrig", "2x")


def test_names_are_relative_except_the_ros_wide_topics():
    for t in contract.TOPICS:
        contract.validate_name(t.name)
        assert t.name.startswith("/") == (t.name in ("/clock", "/diagnostics")), t.name
    for s in contract.SERVICES:
        assert not s.name.startswith("/")
    assert set(contract.PER_SAMPLE_TOPICS) <= {t.name for t in contract.TOPICS}


def test_documented_topics_follow_the_namespace():
    docs = contract.documented_topics("/rig_b")
    assert "/rig_b/state" in docs and "/clock" in docs and "/lubrig/state" not in docs
    assert docs["/rig_b/run_config"].latched and docs["/rig_b/run_config"].depth == 1
    assert not docs["/rig_b/state"].latched and docs["/rig_b/state"].depth == 1000


def test_select_topics_refuses_names_outside_the_contract():
    assert [t.name for t in contract.select_topics("/lubrig", ["state", "/clock"])] == [
        "/lubrig/state",
        "/clock",
    ]
    with pytest.raises(ValueError, match="'nope' is not in the topic contract"):
        contract.select_topics("/lubrig", ["nope"])


def test_parameter_check_names_value_and_range():
    p = contract.parameter("plant", "realtime_priority")
    assert p.check(0) == 0 and p.check(99) == 99
    with pytest.raises(ParameterError, match=r"realtime_priority=150 is not valid; expected 0\.\.99"):
        p.check(150)
    stale = contract.parameter("plant", "stale_timeout")
    for bad in (0.0, -1.0, float("nan"), float("inf"), "x", True):
        with pytest.raises(ParameterError, match="stale_timeout"):
            stale.check(bad)
    mode = contract.parameter("belt_drive", "mode")
    with pytest.raises(ParameterError, match=r"expected one of \['sim', 'realtime'\]"):
        mode.check("rig_in_loop")
    window = contract.parameter("analysis", "window")
    with pytest.raises(ParameterError, match=r"expected 64\.\.65536"):
        window.check(63)
    with pytest.raises(ParameterError):
        window.check(100.0)  # a double for an integer parameter


def test_every_parameter_has_a_description_and_a_default_source():
    for node, params in contract.NODE_PARAMETERS.items():
        names = [p.name for p in params]
        assert len(names) == len(set(names)), node
        for p in params:
            assert p.description, (node, p.name)
            assert (p.default is None) == bool(p.from_config), (node, p.name)
            if p.default is not None:
                p.check(p.default)  # the default itself is valid


ROOT = Path(__file__).resolve().parents[1]


def test_doc_tables_are_generated_from_the_contract():
    """README.md, docs/topics.md and docs/nodes.md hold the contract's tables, up to date."""
    assert contract_docs.problems(ROOT) == []
    topics = (ROOT / "docs" / "topics.md").read_text()
    for t in contract.TOPICS:  # every topic with its resolved name, type and QoS
        assert f"`{contract.resolve('/lubrig', t.name)}`" in topics
    nodes = (ROOT / "docs" / "nodes.md").read_text()
    for node, params in contract.NODE_PARAMETERS.items():
        for p in params:
            assert f"| `{p.name}` |" in nodes, (node, p.name)


def test_a_stale_table_is_detected(tmp_path):
    for name in contract_docs.DOCUMENTS:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text((ROOT / name).read_text())
    topics = tmp_path / "docs" / "topics.md"
    topics.write_text(topics.read_text().replace("keep_last 1000", "keep_last 999", 1))
    assert contract_docs.problems(tmp_path) == [
        "docs/topics.md: generated tables differ from app/interface/contract.py"
    ]
    assert contract_docs.main([str(tmp_path), "--check"]) == 1
    assert contract_docs.main([str(tmp_path)]) == 0  # rewrite
    assert contract_docs.problems(tmp_path) == []


def test_nodes_yaml_sets_only_contract_parameters_with_valid_values():
    data = yaml.safe_load((ROOT / "config" / "nodes.yaml").read_text())
    assert data, "config/nodes.yaml is empty"
    for key, section in data.items():
        params = section["ros__parameters"]
        # keys: /** (every node) or /**/<node> (that node in any namespace)
        nodes = list(contract.NODE_PARAMETERS) if key == "/**" else [key.removeprefix("/**/")]
        assert set(nodes) <= set(contract.NODE_PARAMETERS), key
        for node in nodes:
            for name, value in params.items():
                spec = contract.parameter(node, name)  # KeyError: not in the contract
                spec.check(value)
                if spec.default is not None:
                    # the file restates the contract's defaults (it documents them for users)
                    assert value == spec.default, (node, name, value, spec.default)
