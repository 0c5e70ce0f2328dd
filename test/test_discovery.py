"""Discovery kept on this host by default (app/processes/discovery.py): the environment rig processes get."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from lubrig_ros.app.processes.discovery import (
    DISCOVERY_VARIABLE,
    PROFILE_VARIABLE,
    RANGE_VARIABLE,
    discovery_environment,
    localhost_profile,
)
from lubrig_ros.core.params import ParameterError


def test_default_is_this_host_only_range_and_transports():
    d = discovery_environment({"PATH": "/bin"})
    assert d.choice == "localhost"
    assert d.env[RANGE_VARIABLE] == "LOCALHOST"
    assert d.env[PROFILE_VARIABLE] == str(localhost_profile())
    assert d.env["PATH"] == "/bin"
    assert "this host only" in d.isolation


def test_network_on_request_by_option_or_variable():
    inherited = {PROFILE_VARIABLE: str(localhost_profile()), RANGE_VARIABLE: "LOCALHOST"}
    for d in (
        discovery_environment(inherited, network=True),
        discovery_environment({**inherited, DISCOVERY_VARIABLE: "network"}),
    ):
        assert d.choice == "network"
        assert d.env[RANGE_VARIABLE] == "SUBNET"
        assert PROFILE_VARIABLE not in d.env  # our loopback profile is not carried onto the network
        assert "any host" in d.isolation


def test_a_users_own_fastdds_profile_is_kept_and_named():
    d = discovery_environment({PROFILE_VARIABLE: "/etc/my_dds.xml"})
    assert d.env[PROFILE_VARIABLE] == "/etc/my_dds.xml"
    assert d.env[RANGE_VARIABLE] == "LOCALHOST"
    assert "/etc/my_dds.xml" in d.isolation
    assert discovery_environment({PROFILE_VARIABLE: "/etc/my_dds.xml"}, True).env[PROFILE_VARIABLE] == (
        "/etc/my_dds.xml"
    )


def test_a_bad_variable_value_names_it_and_the_choices():
    with pytest.raises(ParameterError, match=r"LUBRIG_DISCOVERY='everywhere'.*'localhost', 'network'"):
        discovery_environment({DISCOVERY_VARIABLE: "everywhere"})


def test_the_shipped_profile_binds_udp_to_loopback_and_replaces_the_builtin_transports():
    root = ET.parse(localhost_profile()).getroot()
    ns = {"d": "http://www.eprosima.com"}
    descriptors = root.iterfind(".//d:transport_descriptor", ns)
    udp = [t for t in descriptors if t.findtext("d:type", "", ns) == "UDPv4"]
    assert len(udp) == 1
    assert [a.text for a in udp[0].iterfind("d:interfaceWhiteList/d:address", ns)] == ["127.0.0.1"]
    participant = root.find(".//d:participant", ns)
    assert participant is not None and participant.get("is_default_profile") == "true"
    assert participant.findtext("d:rtps/d:useBuiltinTransports", "", ns) == "false"
