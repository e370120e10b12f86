"""A component's stderr reaches the launch's own, and the launch can say why the component died."""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from plem.launch.child_errors import ErrorTail
from plem.launch.supervisor import Child

_DIES = """
import logging, sys
logging.basicConfig(format="[bridge] %(levelname)s: %(message)s")
logging.getLogger().warning("a warning first")
print("progress", file=sys.stderr)
raise ValueError("the cylinder's radius is -1")
"""


@pytest.mark.parametrize(("code", "said"), [
    (_DIES, "ValueError: the cylinder's radius is -1"),
    ("import logging; logging.basicConfig(format='[bridge] %(levelname)s: %(message)s'); "
     "logging.error('cannot publish: the name is too long'); print('bye', file=__import__('sys').stderr); exit(1)",
     "[bridge] ERROR: cannot publish: the name is too long"),
    ("import sys; print('just a line', file=sys.stderr); sys.exit(3)", "just a line"),
])
def test_the_last_error_line_of_a_dead_child_names_why_it_died(code: str, said: str):
    process = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.PIPE, text=True)
    forwarded = io.StringIO()
    assert process.stderr is not None
    child = Child("arm", "bridge", process, critical=False, errors=ErrorTail(process.stderr, forwarded))
    process.wait(30)
    assert child.death() == f"exited with code {process.returncode}: {said}"
    assert said in forwarded.getvalue(), "the child's stderr was not passed on"


def test_a_child_that_said_nothing_is_described_by_its_end_alone():
    process = subprocess.Popen([sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGKILL)"],
                               stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    child = Child("arm", "bridge", process, critical=False, errors=ErrorTail(process.stderr, io.StringIO()))
    process.wait(30)
    assert child.death() == "killed by SIGKILL"
