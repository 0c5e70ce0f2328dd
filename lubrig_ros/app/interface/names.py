"""ROS 2 names without ROS: the one validator of namespaces and topic/service names, and resolution.

Part of the rig's interface contract (app/interface/contract.py re-exports every name here). The rules are
ROS 2's (rmw_validate_namespace, rcl's name resolution); test/test_contract.py checks them
against rclpy's own validator.
"""

from __future__ import annotations

import re

from ...core.params import ParameterError

#: Longest namespace ROS 2 accepts (rmw: RMW_NAMESPACE_MAX_NAME_LENGTH; measured with rclpy: 245).
NAMESPACE_MAX_LENGTH = 245

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _name_problem(name: str, *, namespace: bool) -> str | None:
    """Why `name` breaks ROS 2's rules for a namespace (or a topic/service name), else None."""
    kind = "namespace" if namespace else "name"
    if not name:
        return f"a {kind} must not be empty"
    if namespace and not name.startswith("/"):
        return "a namespace must be absolute (start with '/')"
    bad = sorted({c for c in name if not (c.isascii() and (c.isalnum() or c in "_/"))})
    if bad:
        return f"a {kind} may hold only letters, digits, '_' and '/' (not {''.join(bad)!r})"
    if "//" in name:
        return f"a {kind} must not contain '//'"
    if name.endswith("/") and name != "/":
        return f"a {kind} must not end with '/' (unless it is just '/')"
    if not namespace and name == "/":
        return "a name must not be just '/'"
    tokens = [t for t in name.split("/") if t]
    if any(not _TOKEN.match(t) for t in tokens):
        return f"no token of a {kind} may start with a digit"
    if namespace and len(name) > NAMESPACE_MAX_LENGTH:
        return f"a namespace may have at most {NAMESPACE_MAX_LENGTH} characters (has {len(name)})"
    return None


def validate_namespace(namespace: str, what: str = "namespace") -> str:
    """Return `namespace` if it is a valid ROS 2 namespace, else ParameterError (a ValueError).

    ROS 2's rules (rmw_validate_namespace; test/test_contract.py checks against rclpy's own
    validator): absolute, only letters, digits, '_' and '/', no '//', no trailing '/' (except
    the root namespace '/'), no token starting with a digit, at most 245 characters. So
    '/lubrig', '/rig_2' and '/' are valid; '/rig-2', 'lubrig', '/lubrig/' and '/2rig' are not.
    """
    if not isinstance(namespace, str):
        raise ParameterError(f"{what}={namespace!r} is not valid; expected a string such as '/lubrig'")
    problem = _name_problem(namespace, namespace=True)
    if problem:
        raise ParameterError(
            f"{what}={namespace!r} is not valid: {problem}; expected an absolute ROS name such as "
            "'/lubrig' or '/rig_2'"
        )
    return namespace


def validate_name(name: str, what: str = "name") -> str:
    """Return a topic or service name (relative or absolute) if ROS 2 accepts it, else ParameterError."""
    problem = _name_problem(name, namespace=False) if isinstance(name, str) else "not a string"
    if problem:
        raise ParameterError(f"{what}={name!r} is not valid: {problem}")
    return name


def resolve(namespace: str, name: str) -> str:
    """Absolute name of `name` in `namespace` (absolute names are kept), as rcl resolves it."""
    validate_name(name)
    if name.startswith("/"):
        return name
    namespace = validate_namespace(namespace)
    return f"{'' if namespace == '/' else namespace}/{name}"
