"""`plem service call` over every service type plem serves, with requests that name every field of the type.

A request field may have any name, also one of `plem service call`'s own options (SwitchController has `timeout`):
each call must end in a response or a WHAT/WHY/HOW error, never an internal error or a traceback.
"""

from __future__ import annotations

import gc

import pytest

from plem.cli.app import run
from plem.cli.ros_messages import to_yaml
from plem.middleware import controller_manager, moveit, parameters, servo
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.goals import FJT
from plem.middleware.graph import Graph
from plem.middleware.names import ActionNames
from plem.middleware.node import Node
from plem.middleware.types import library
from tests.e2e import planner_launch
from tests.e2e.launched import Launch

launch = planner_launch.launch              # the module's launch, and each test in its domain
same_domain = planner_launch.same_domain

ACTIONS = (FJT, "plem_msgs/action/SetMode", moveit.EXECUTE)


def served_types() -> set[str]:
    """Every service type a launched robot serves, from the tables its servers are built from."""
    types = {f"controller_manager_msgs/srv/{kind}" for kind in controller_manager.SERVICES.values()}
    types |= {f"rcl_interfaces/srv/{kind}" for kind in parameters.SERVICES.values()}
    types |= {f"moveit_msgs/srv/{kind}" for kind in moveit.SERVICES.values()}
    types |= {service_type for action in ACTIONS for _, service_type in ActionNames("/a").services(action)}
    types.add(servo.SPEED_SLIDER)
    return types


@pytest.fixture(scope="module")
def servers(launch: Launch) -> dict[str, str]:
    """Service type → one service of the launched robot that serves it, for every type of `served_types()`."""
    wanted = served_types()
    node = Node(DiscoverySettings.from_environment(launch.env))   # module-scoped: before `same_domain` runs
    graph = Graph(node)

    def found(seen: Graph) -> dict[str, str]:
        return {server.service_type: name for name, info in seen.services().items()
                if name.startswith(f"/{launch.robot_id}/") for server in info.servers}

    graph.discover(60, until=lambda seen: wanted <= set(found(seen)))
    served = found(graph)
    node.close()
    assert wanted <= set(served), f"not served: {sorted(wanted - set(served))}"
    assert set(served) <= wanted, f"served but not enumerated from the code: {sorted(set(served) - wanted)}"
    return served


def call(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = run(["service", "call", *args])
    gc.collect()   # the command's participant leaves the domain now, not whenever the collector runs
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_every_service_type_takes_a_request_that_names_every_field(servers: dict[str, str],
                                                                  capsys: pytest.CaptureFixture[str]):
    interfaces = library()
    for service_type, name in sorted(servers.items()):
        request = to_yaml(interfaces.new(f"{service_type}_Request"))
        code, output = call(capsys, name, service_type, request or "{}", "--timeout", "30")
        assert "Internal error" not in output and "Traceback" not in output, (service_type, output)
        assert code == 0 or ("WHAT:" in output and "HOW:" in output), (service_type, code, output)


def test_switch_controller_takes_its_own_timeout_field(servers: dict[str, str], capsys: pytest.CaptureFixture[str]):
    service_type = "controller_manager_msgs/srv/SwitchController"
    code, output = call(capsys, servers[service_type], service_type,
                        "{activate_controllers: [], deactivate_controllers: [], strictness: 1, timeout: {sec: 2}}")
    assert code == 0, output
    assert "timeout=builtin_interfaces.msg.Duration(sec=2, nanosec=0)" in output and "ok: true" in output, output


def test_a_refused_hardware_state_change_prints_its_reason_from_rosout(launch: Launch, servers: dict[str, str],
                                                                       capsys: pytest.CaptureFixture[str]):
    service_type = "controller_manager_msgs/srv/SetHardwareComponentState"
    code, output = call(capsys, servers[service_type], service_type,
                        "{name: indy7_hardware, target_state: {id: 3, label: active}}")
    assert code == 0 and "ok: false" in output, output
    assert (f"/rosout [{launch.robot_id}.controller_manager] WARN: set_hardware_component_state failed: unknown "
            "hardware component 'indy7_hardware' (this robot has 'indy7_v2_hardware')") in output, output
    code, output = call(capsys, servers[service_type], service_type,   # the name docs/ros2.md gives
                        "{name: indy7_v2_hardware, target_state: {id: 3, label: active}}")
    assert code == 0 and "ok: true" in output and "/rosout" not in output, output


def test_an_unknown_field_is_a_usage_error_for_every_service_type(capsys: pytest.CaptureFixture[str]):
    for service_type in sorted(served_types()):
        code, output = call(capsys, "/nowhere/service", service_type, "{no_such_field: 1}")
        assert code == 2, (service_type, output)
        assert "no_such_field" in output and "WHAT:" in output and "WHY:" in output and "HOW:" in output, output
        assert "Internal error" not in output and "Traceback" not in output, output
