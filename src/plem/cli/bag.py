"""`plem bag info|plot|repair|export`: what the flight recorder's bags hold, a plot of them, repair of killed
segments, and their export into the fleet's Parquet dataset (docs/fleet.md).

DIR is the recorder's bag_dir, one robot's directory in it, or one segment directory. The bag reading
modules are imported inside the commands so other commands start fast.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from plem.cli.output import OutputFormat, new_table, print_json, print_warnings, stdout
from plem.errors import PlemError, raise_collected

if TYPE_CHECKING:
    from plem.recording.summary import RobotBags, RobotSummary, SegmentInfo
    from plem.recording.time_range import TimePoint

app = typer.Typer(help="Inspect, plot, repair and export the flight recorder's bags.", no_args_is_help=True)

Directory = Annotated[Path, typer.Argument(metavar="DIR", show_default=False, help="The recorder's bag_dir, one "
                                                "robot's directory in it, or one segment directory.")]


def _size(size: float) -> str:
    units = ("B", "KiB", "MiB", "GiB", "TiB")
    index = 0
    while size >= 1024 and index < len(units) - 1:
        size, index = size / 1024, index + 1
    return f"{size:.0f} B" if index == 0 else f"{size:.1f} {units[index]}"


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.3f} s"
    minutes, rest = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min {rest:02d} s" if hours else f"{minutes} min {rest:02d} s"


def _count(count: int, noun: str) -> str:
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def _iso(ns: int | None) -> str | None:
    from plem.recording.archive import iso_time

    return None if ns is None else iso_time(ns)


def _messages(segment: SegmentInfo, robot_id: str) -> str:
    """Message counts per topic, the robot's namespace left out."""
    prefix = f"/{robot_id}/"
    return ", ".join(f"{topic.removeprefix(prefix)} {count}" for topic, (_, count) in sorted(segment.topics.items()))


def _totals(summaries: list[RobotSummary]) -> dict[str, Any]:
    segments = [segment for summary in summaries for segment in summary.segments]
    messages: Counter[str] = Counter()
    for segment in segments:
        messages.update({topic: count for topic, (_, count) in segment.topics.items()})
    return {"segments": len(segments), "complete": sum(segment.state == "complete" for segment in segments),
            "covered_s": sum(segment.duration_ns or 0 for segment in segments) / 1e9,
            "bytes": sum(segment.size for segment in segments), "messages": dict(sorted(messages.items()))}


def _segment_json(segment: SegmentInfo) -> dict[str, Any]:
    return {"name": segment.name, "path": str(segment.path), "storage": segment.storage, "state": segment.state,
            "note": segment.note(), "kept": segment.kept, "start": _iso(segment.start_ns),
            "start_ns": segment.start_ns,
            "duration_s": None if segment.duration_ns is None else segment.duration_ns / 1e9,
            "bytes": segment.size, "messages": {topic: count for topic, (_, count) in segment.topics.items()}}


def _robot_json(summary: RobotSummary) -> dict[str, Any]:
    drops = summary.drops
    recorder = summary.recorder and {**summary.recorder, "time": _iso(summary.recorder["time_ns"])}
    return {
        "robot_id": summary.robot_id, "directory": str(summary.directory),
        "segments": [_segment_json(segment) for segment in summary.segments],
        "totals": _totals([summary]),
        "drops": {"rt_raw": {"samples": drops.samples, "gaps": drops.gap_count, "missing_cycles": drops.missing,
                             "new_runs": drops.new_runs, "listed_gaps": [asdict(gap) for gap in drops.gaps],
                             "not_compared_across": drops.not_compared},
                  "recorder": recorder},
        "faults": summary.faults,
        "deletions": {"count": sum(count for _, count in summary.deletions),
                      "reasons": [{"reason": reason, "count": count} for reason, count in summary.deletions]},
        "stops": {"count": len(summary.stops), "not_recorded": _not_recorded(summary),
                  "entries": summary.stops},
        "problems": [problem.to_dict() for problem in summary.problems],
    }


def _not_recorded(summary: RobotSummary) -> int:
    """Messages the recorder could not record while stopped, as its event log counts them."""
    return sum(int(entry.get("not_recorded", 0)) for entry in summary.stops)


def _fault_line(entry: dict[str, Any]) -> str:
    """When (bag time), which cycle, why, and where in the bags a fault is."""
    where = (f"segment {entry['segment']} at {float(entry.get('offset_s', 0)):.3f} s" if entry.get("segment")
             else "not recorded (recording stopped)")
    when = entry.get("time_in_bag") or entry.get("time")
    return f"  {when} cycle {entry.get('cycle')}: {entry.get('reason')} — {where}"


def _print_robot(summary: RobotSummary) -> None:
    table = new_table(f"{summary.robot_id}: {summary.directory}", "segment", "storage", "start (UTC)", "duration",
                      "size", "messages", "status")
    for segment in summary.segments:
        status = ", ".join(part for part in (segment.note(), "kept for a fault" if segment.kept else "") if part)
        duration = "" if segment.duration_ns is None else _duration(segment.duration_ns / 1e9)
        table.add_row(segment.name, segment.storage, _iso(segment.start_ns) or "", duration, _size(segment.size),
                      _messages(segment, summary.robot_id), status)
    stdout.print(table)
    drops = summary.drops
    lines = [f"rt_raw: {_count(drops.samples, 'sample')}, {_count(drops.missing, 'cycle')} missing in "
             f"{_count(drops.gap_count, 'gap')}, {_count(drops.new_runs, 'new driver run')}"]
    lines += [f"  {gap.segment} at {gap.offset_s:.3f} s: {_count(gap.missing, 'cycle')} missing after cycle "
              f"{gap.after_cycle}" for gap in drops.gaps]
    if drops.gap_count > len(drops.gaps):
        lines.append(f"  ... {_count(drops.gap_count - len(drops.gaps), 'more gap')}")
    if drops.not_compared:
        lines.append(f"  cycles not compared across: {', '.join(drops.not_compared)}")
    recorder = summary.recorder
    if recorder is None:
        lines.append("recorder: no rt_monitor_stats recorded")
    else:
        rings = ", ".join(f"{name} {count}" for name, count in recorder["ring_dropped"].items()) or "none reported"
        lines.append(f"recorder (last rt_monitor_stats, {_iso(recorder['time_ns'])}): "
                     f"{recorder['bag_dropped'] if recorder['bag_dropped'] is not None else 'unknown'} messages "
                     f"not recorded; ring records lost: {rings}")
    lines.append(f"faults: {len(summary.faults)}")
    lines += [_fault_line(entry) for entry in summary.faults]
    deleted = sum(count for _, count in summary.deletions)
    reasons = "; ".join(f"{count} × {reason}" for reason, count in summary.deletions)
    lines.append(f"deletions: {deleted}" + (f" — {reasons} (latest reason of each kind)" if deleted else ""))
    if summary.stops:
        lines.append(f"recording stopped {_count(len(summary.stops), 'time')}: {_not_recorded(summary)} messages "
                     "not recorded")
        lines += [f"  {entry.get('time')}: {entry.get('reason')} — {entry.get('not_recorded')} not recorded in "
                  f"{entry.get('stopped_s')} s" for entry in summary.stops]
    typer.echo("\n".join(lines) + "\n")


@app.command("info")
def info(
    directory: Directory,
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = OutputFormat.text,
) -> None:
    """Segments, message counts, dropped cycles, faults and deletions of the bags under DIR."""
    from plem.recording.summary import find_bags, summarise

    summaries = [summarise(robot) for robot in find_bags(directory)]
    totals = _totals(summaries)
    if output_format is OutputFormat.json:
        print_json({"directory": str(directory), "robots": [_robot_json(summary) for summary in summaries],
                    "totals": totals})
    else:
        for summary in summaries:
            _print_robot(summary)
        messages = ", ".join(f"{topic} {count}" for topic, count in totals["messages"].items())
        typer.echo(f"total: {_count(totals['segments'], 'segment')} ({totals['complete']} complete), "
                   f"{_duration(totals['covered_s'])} covered, {_size(totals['bytes'])}; messages: "
                   f"{messages or 'none'}")
    raise_collected([problem for summary in summaries for problem in summary.problems], f"the bags under {directory}")


def _refuse_output(out: Path) -> None:
    """--out must name a regular file (or none yet) in an existing directory: never a device, never a new folder."""
    import os
    import stat

    from plem.core.files import file_kind
    from plem.recording.summary import BagError

    what = "a PNG file path in an existing directory"
    try:
        mode = os.lstat(out).st_mode
    except FileNotFoundError:
        mode = None
    except (OSError, ValueError) as error:
        raise BagError(f"cannot write {out}", what=what, why=getattr(error, "strerror", None) or str(error),
                       how="pass --out with a path in a writable directory") from None
    if mode is not None and not stat.S_ISREG(mode):
        raise BagError(f"{out} is not a regular file", what=f"{what}; an existing file there is replaced",
                       why=f"{out} is a {file_kind(mode)}, which plem does not replace",
                       how="pass --out with the path of a new or regular .png file")
    parent = out.parent
    if not parent.is_dir():
        raise BagError(f"cannot write {out}: {parent} is not a directory", what=what,
                       why=f"{parent} does not exist" if not parent.exists() else f"{parent} is not a directory",
                       how=f"create it first (mkdir -p {parent}), or pass --out in an existing directory")


def _robots_to_plot(found: list[RobotBags], robot: str | None, directory: Path,
                    out: Path) -> list[tuple[RobotBags, Path]]:
    """The robots --robot names (default: the one whose last message is latest, said when there are others) and the
    PNG of each."""
    from plem.recording.summary import pick_robot

    if robot == "all":
        return [(bags, out.with_name(f"{out.stem}-{bags.robot_id}{out.suffix}")) for bags in found]
    chosen, warnings = pick_robot(found, robot, directory, "plotting", ", or --robot all for one PNG per robot")
    print_warnings(warnings)
    return [(chosen, out)]


def _plot_robot(robot: RobotBags, out: Path, directory: Path, start: TimePoint | None, end: TimePoint | None) -> None:
    """Write one robot's plot between --from and --to, saying which segments it reads only in part or leaves out."""
    from plem.core.files import write_atomic
    from plem.recording.plot import render
    from plem.recording.summary import BagError, robot_segments
    from plem.recording.time_range import time_range
    from plem.recording.timeline import extent, segment_warnings, timeline_of

    segments = robot_segments(robot)
    print_warnings(segment_warnings(segments))
    timeline = timeline_of(robot.robot_id, segments, *time_range(start, end, extent(segments)))
    png = render(timeline, f"{robot.robot_id}: {directory}")
    try:
        write_atomic(out, png)
    except OSError as error:
        raise BagError(f"cannot write {out}", what="a PNG file plem may write",
                       why=error.strerror or str(error),
                       how="pass --out with a path in a writable directory") from error
    typer.echo(f"wrote {out} ({_size(len(png))}): {robot.robot_id} from {_iso(int(timeline.time_ns[0]))} to "
               f"{_iso(int(timeline.time_ns[-1]))}")


TIME_FORMS = "2026-11-24T18:30:05, 18:30:05 (UTC, on the recording's day) or +12.5 (seconds after its start)"


@app.command("plot")
def plot(
    directory: Directory,
    out: Annotated[Path, typer.Option("--out", "-o", help="PNG file to write (with --robot all: one per robot, "
                                      "named OUT-ROBOT_ID.png).", show_default=False)],
    robot: Annotated[str | None, typer.Option("--robot", help="Robot to plot when DIR holds several (default: the "
                                              "one whose last message is latest; all: every one).",
                                              show_default=False)] = None,
    start: Annotated[str | None, typer.Option("--from", help=f"Plot from this time: {TIME_FORMS}.",
                                              show_default=False)] = None,
    end: Annotated[str | None, typer.Option("--to", help=f"Plot up to this time: {TIME_FORMS}.",
                                            show_default=False)] = None,
) -> None:
    """Plot measured and commanded joint positions, velocities and the loop's latency over time, with the modes and
    faults, and a histogram of the latency."""
    from plem.recording.summary import find_bags
    from plem.recording.time_range import parse_time

    first, last = parse_time(start, "--from"), parse_time(end, "--to")
    targets = _robots_to_plot(find_bags(directory), robot, directory, out)
    for _, path in targets:
        _refuse_output(path)
    problems: list[PlemError] = []
    for bags, path in targets:
        try:
            _plot_robot(bags, path, directory, first, last)
        except PlemError as error:
            problems.append(error)
    raise_collected(problems, f"the plots of {directory}")


@app.command("repair")
def repair(directory: Directory) -> None:
    """Rebuild every unfinished (killed) or damaged segment under DIR into a readable bag; others are left alone."""
    from plem.recording.repair import repair as repair_segment
    from plem.recording.summary import BagError, find_bags, robot_segments

    failures: list[tuple[str, PlemError]] = []
    for robot in find_bags(directory):
        for segment in robot_segments(robot):
            if segment.state == "complete":
                typer.echo(f"{segment.name}: already complete")
            elif segment.state == "recording":
                typer.echo(f"{segment.name}: left alone, a recorder is writing it")
            elif segment.state == "unreadable":
                failures.append((segment.name, BagError(
                    f"{segment.name} cannot be rebuilt", what="a segment whose bag file or metadata.yaml reads",
                    why=segment.problem, how="restore its files, or delete the segment")))
            else:
                try:
                    report = repair_segment(segment.path)
                except PlemError as error:
                    failures.append((segment.name, error))
                    continue
                typer.echo(f"{segment.name}: repaired, {report.messages} messages recovered" if report.repaired
                           else f"{segment.name}: reads back whole ({report.messages} messages), left alone")
    for name, failure in failures:
        typer.echo(f"{name}: not repaired: {failure.summary}")
    if failures:
        raise BagError(f"{_count(len(failures), 'segment')} could not be repaired", what="every killed segment rebuilt",
                       why="; ".join(f"{name}: {failure.why}" for name, failure in failures),
                       how="; ".join(dict.fromkeys(failure.how for _, failure in failures)))


@app.command("export")
def export(
    directories: Annotated[list[Path], typer.Argument(metavar="BAG_DIR...", show_default=False, help="The "
                                                      "recorder's bag_dir, one robot's directory in it, or one "
                                                      "segment directory; several may be given.")],
    to: Annotated[str, typer.Option("--to", metavar="DEST", show_default=False, help="The dataset: a directory, or "
                                    "s3://BUCKET/PREFIX (credentials from the usual AWS_* variables).")],
) -> None:
    """Export the closed segments under BAG_DIR into a Parquet dataset (one table per topic, Hive-partitioned by
    robot_id and date); segments exported before are skipped, so it can run again at any time."""
    from plem.fleet.destination import open_destination
    from plem.fleet.export import export as export_bags

    destination = open_destination(to)
    report = export_bags(directories, destination)
    for path in report.removed_temporaries:
        typer.echo(f"removed {path}, left by an export that was killed")
    for name in report.recording:
        typer.echo(f"{name}: being recorded, exported once closed")
    typer.echo(f"exported {_count(len(report.exported), 'segment')} ({report.rt_raw_rows} rt_raw rows, "
               f"{_count(report.files, 'file')}, {_size(report.bytes)}) to {to}; "
               f"{len(report.already)} exported before")
    raise_collected(report.problems, f"the export of {', '.join(map(str, directories))}")
