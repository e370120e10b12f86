"""A user's mypy sees real types for plem's public API: the package ships `py.typed` and its names are annotated."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

USER_CODE = textwrap.dedent("""
    from plem.bridge import connect
    from plem.core.config import load_config
    from plem.fieldbus import MockBus
    from plem.robot import Indy7V2, Robot, SerialArmConfig

    config: SerialArmConfig = Indy7V2(rt_priority=80)
    config.custom_bus = MockBus(6)
    robot = Robot.builder(config).with_robot_id("arm_left").build()
    reveal_type(robot)
    state = robot.state()
    assert state is not None
    reveal_type(state.position)
    reveal_type(connect)
    reveal_type(load_config("robot.yaml", "robot.control.timeout", int))
    reveal_type(SerialArmConfig.validate)
    rt: int = config.rt_priority
""")


def test_a_users_strict_mypy_sees_plems_types(tmp_path: Path):
    script = tmp_path / "user.py"
    script.write_text(USER_CODE)
    result = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--follow-imports=silent",
                             str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    revealed = [line for line in result.stdout.splitlines() if "Revealed type" in line]
    assert len(revealed) == 5, result.stdout
    assert not any('"Any"' in line for line in revealed), result.stdout
    assert '"plem.robot.robot.Robot"' in revealed[0] and '"int"' in revealed[3], result.stdout
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert errors == [], result.stdout
