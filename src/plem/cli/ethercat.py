"""`plem ethercat scan|simulate`: what answers on an EtherCAT interface, and the virtual network without hardware."""

from __future__ import annotations

from typing import Annotated

import typer

from plem.cli.output import OutputFormat, new_table, print_json, stdout

app = typer.Typer(help="Inspect EtherCAT segments and run the virtual EtherCAT network.", no_args_is_help=True)


@app.command("scan")
def scan(
    interface: Annotated[str | None, typer.Argument(
        help="Network interface (default: MASTER0_DEVICE of /opt/etherlab/etc/ethercat.conf, else eth0).",
        show_default=False)] = None,
    output: Annotated[OutputFormat, typer.Option("--format", help="text or json.")] = OutputFormat.text,
) -> None:
    """List every slave on the interface: position, name, ids, AL state and code, CoE and DC."""
    from plem.fieldbus.ethercat.bringup import default_interface
    from plem.fieldbus.ethercat.scan import scan as scan_segment

    interface = interface or default_interface(0) or "eth0"
    slaves = scan_segment(interface)
    if output is OutputFormat.json:
        print_json({"interface": interface, "slaves": [slave.as_dict() for slave in slaves]})
        return
    table = new_table(f"{interface}: {len(slaves)} slave{'s' if len(slaves) != 1 else ''}", "pos", "name",
                      "vendor", "product", "revision", "state", "AL status", "CoE", "DC")
    for s in slaves:
        table.add_row(str(s.position), s.name, f"0x{s.vendor_id:08X}", f"0x{s.product_code:08X}",
                      f"0x{s.revision:08X}", s.state, f"0x{s.al_status_code:04X} {s.al_status}",
                      "yes" if s.coe else "no", "yes" if s.distributed_clocks else "no")
    stdout.print(table)


@app.command("simulate")
def simulate(
    arguments: Annotated[list[str] | None, typer.Argument(
        help="Launch arguments naming the arm, e.g. robot_type:=indy7_v2, description_package:=PKG, "
             "cycle_time:=1000; master_index:=N numbers the network.", show_default=False)] = None,
    encoder_zero: Annotated[str | None, typer.Option(
        "--encoder-zero", help="Raw encoder reading of each drive at home (comma-separated counts), to practise "
                               "calibration; default 0.", show_default=False)] = None,
    missing_object: Annotated[list[str] | None, typer.Option(
        "--missing-object", help="An object index the drives leave out of their dictionaries, as drives that "
                                 "implement fewer objects do (e.g. 0x6076, the rated torque); repeatable.",
        show_default=False)] = None,
) -> None:
    """Run the virtual EtherCAT network of an arm until Ctrl-C and print the launch line that drives it."""
    from plem.core.config.settings import parse_int_list
    from plem.errors import UsageError
    from plem.fieldbus.ethercat.virtual.emulator import VirtualNetwork
    from plem.launch.arguments import initial_positions, parse
    from plem.launch.component import stop_on_signals
    from plem.launch.ethercat_sim import arm_of_plan
    from plem.launch.plan import plan_robot

    values = parse(arguments or [])
    start_text = values.pop("initial_positions", None)   # the emulated arm's, not the master's launch argument
    plan = plan_robot({**values, "bus": "ethercat"}, generate=False)
    zero = None
    if encoder_zero is not None:
        try:
            zero = tuple(parse_int_list(encoder_zero))
        except ValueError:
            raise UsageError("--encoder-zero must be whole numbers separated by commas",
                             what="one raw count per joint", why=f"found {encoder_zero!r}",
                             how="e.g. --encoder-zero=1000,-2000,0,0,0,0") from None
    missing = frozenset(_object_index(text) for text in missing_object or [])
    start = None if start_text is None else initial_positions(start_text, "ethercat_sim", plan.limits())
    network = VirtualNetwork(arm_of_plan(plan, zero, missing, start), index=plan.config.master_index)
    network.stop = stop_on_signals()
    given = " ".join(f"{name}:={value}" for name, value in values.items() if name != "bus")

    def announce(running: VirtualNetwork) -> None:
        stdout.print(f"virtual EtherCAT network {running.index}: {len(running.identities)} emulated CiA402 drives "
                     f"behind {running.master_interface}\nDrive it with the real EtherCAT master:\n"
                     f"  plem launch bus:=ethercat eth_interface:={running.master_interface} {given}".rstrip()
                     + f"\n  plem ethercat scan {running.master_interface}\nCtrl-C removes the network.",
                     markup=False)

    network.run(ready=announce)


def _object_index(text: str) -> int:
    """An object index of --missing-object: 0x0000-0xFFFF, in hex (0x...) or decimal."""
    from plem.errors import UsageError

    try:
        index = int(text, 0)
    except ValueError:
        index = -1
    if not 0 <= index <= 0xFFFF:
        raise UsageError(f"--missing-object {text!r} is not an object index",
                         what="an object index from 0x0000 to 0xFFFF, in hex (0x...) or decimal",
                         why=f"got {text!r}", how="e.g. --missing-object 0x6076")
    return index


INJECTIONS = {
    "drive-fault": ("drive_fault", "drive=N code=0x7121 [persistent=true]: drive N faults with that 0x603F code"),
    "clear-fault": ("clear_fault", "drive=N: the cause of a persistent fault is gone"),
    "refuse-enable": ("refuse_enable", "drive=N [refuse=false]: drive N stays switched on when enabled"),
    "drop-frames": ("drop_rate", "rate=0.01: the share of frames lost on the way"),
    "delay-frames": ("delay", "seconds=0.002: every answer comes back this late"),
    "push": ("push", "drive=N torque=T: an external torque of T N·m on drive N's joint (0 takes it away)"),
    "inputs": ("inputs", "drive=N value=0x10000: what drive N reports as its digital inputs (0x60FD)"),
    "disappear": ("disappear", "slave=N: slave N neither answers nor counts"),
    "reappear": ("reappear", "slave=N: slave N is back on the line"),
    "state": ("state", "the emulated arm's true positions, the drives' statuswords and torque offsets"),
}


def _value(text: str, item: str) -> bool | int | float:
    """A name=value's value: true/false, an integer (0x... for hex), or a number."""
    from plem.errors import UsageError

    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    for parse in (lambda t: int(t, 0), float):
        try:
            return parse(text)
        except ValueError:
            continue
    raise UsageError(f"{item!r} has no usable value", what="true, false, an integer (0x... for hex) or a number",
                     why=f"got {text!r}", how="e.g. drive=2 code=0x7121, or rate=0.01")


@app.command("inject", context_settings={"help_option_names": ["--help", "-h"]})
def inject(
    fault: Annotated[str, typer.Argument(help="; ".join(f"{name} {text}" for name, (_, text) in INJECTIONS.items()),
                                         show_default=False)],
    values: Annotated[list[str] | None, typer.Argument(help="name=value pairs.", show_default=False)] = None,
    index: Annotated[int, typer.Option("--index", help="The virtual network's number (its master_index).")] = 0,
) -> None:
    """Inject a fault into a running virtual EtherCAT network (or read its true state)."""
    import json

    from plem.errors import UsageError
    from plem.fieldbus.ethercat.virtual.emulator import Control

    if fault not in INJECTIONS:
        raise UsageError(f"unknown fault {fault!r}", what=f"one of {', '.join(INJECTIONS)}", why=f"got {fault!r}",
                         how="run `plem ethercat inject --help`")
    fields: dict[str, object] = {}
    for item in values or []:
        name, separator, text = item.partition("=")
        if not separator:
            raise UsageError(f"{item!r} is not name=value", what="name=value pairs, e.g. drive=2 code=0x7121",
                             why=f"got {item!r}", how=f"plem ethercat inject {fault} {INJECTIONS[fault][1]}")
        fields[name] = _value(text, item)
    answer = Control(index).request(INJECTIONS[fault][0], **fields)
    print_json(answer) if fault == "state" else stdout.print(f"{fault}: done ({json.dumps(fields)})", markup=False)
