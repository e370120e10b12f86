"""`plem doctor`: whether this host is ready to run a robot in real time over EtherCAT, and how to make it so."""

from __future__ import annotations

from typing import Annotated

import typer

from plem.cli.output import OutputFormat, print_json, stderr, stdout
from plem.fieldbus.ethercat.host import Finding, check_host, ready

LABELS = {"error": "FAIL", "warning": "WARN", "info": "info"}


def _label(finding: Finding) -> str:
    return "ok" if finding.ok else LABELS[finding.severity]


def _verdict(findings: list[Finding]) -> str:
    counts = {severity: sum(not f.ok and f.severity == severity for f in findings) for severity in LABELS}
    return (f"{'READY' if ready(findings) else 'NOT READY'}: {counts['error']} error(s), "
            f"{counts['warning']} warning(s), {counts['info']} note(s)")


def doctor(
    interface: Annotated[str | None, typer.Argument(
        help="Network interface wired to the robot (e.g. enp3s0); without it, candidates are listed.",
        show_default=False)] = None,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
) -> None:
    """Check this host for real-time EtherCAT: kernel, limits, capabilities, CPUs and the robot's interface.

    Exits 1 when a check fails with an error, 0 when only warnings or notes remain.
    """
    findings = check_host(interface)
    if output_format is OutputFormat.json:
        print_json({"ready": ready(findings), "findings": [f.to_dict() for f in findings]})
    else:
        for finding in findings:
            stdout.print(f"{_label(finding):<4}  {finding.summary}", markup=False)
        for finding in findings:
            if not finding.ok:
                stderr.print("\n" + finding.render(), markup=False)
        stdout.print("\n" + _verdict(findings), markup=False)
    if not ready(findings):
        raise typer.Exit(1)
