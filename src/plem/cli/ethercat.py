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
) -> None:
    """Run the virtual EtherCAT network of an arm until Ctrl-C and print the launch line that drives it."""
    from plem.core.config.settings import parse_int_list
    from plem.errors import UsageError
    from plem.fieldbus.ethercat.virtual.emulator import VirtualNetwork
    from plem.launch.arguments import parse
    from plem.launch.component import stop_on_signals
    from plem.launch.ethercat_sim import arm_of_plan
    from plem.launch.plan import plan_robot

    values = parse(arguments or [])
    plan = plan_robot({**values, "bus": "ethercat"}, generate=False)
    zero = None
    if encoder_zero is not None:
        try:
            zero = tuple(parse_int_list(encoder_zero))
        except ValueError:
            raise UsageError("--encoder-zero must be whole numbers separated by commas",
                             what="one raw count per joint", why=f"found {encoder_zero!r}",
                             how="e.g. --encoder-zero=1000,-2000,0,0,0,0") from None
    network = VirtualNetwork(arm_of_plan(plan, zero), index=plan.config.master_index)
    network.stop = stop_on_signals()
    given = " ".join(f"{name}:={value}" for name, value in values.items() if name != "bus")

    def announce(running: VirtualNetwork) -> None:
        stdout.print(f"virtual EtherCAT network {running.index}: {len(running.identities)} emulated CiA402 drives "
                     f"behind {running.master_interface}\nDrive it with the real EtherCAT master:\n"
                     f"  plem launch bus:=ethercat eth_interface:={running.master_interface} {given}".rstrip()
                     + f"\n  plem ethercat scan {running.master_interface}\nCtrl-C removes the network.",
                     markup=False)

    network.run(ready=announce)
