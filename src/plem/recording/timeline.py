"""One robot's recording as a timeline: what `plem bag plot` draws and the 3D replay shows.

rt_raw is read straight from the bags: only the fields kept are gathered, and only for at most
`MAX_POINTS` evenly spaced samples; the latency of every sample in the range is kept for histograms and
percentiles. Faults, their clearing and mode changes come from rt_events, the URDF from the
robot_description recorded with every segment. Complete segments are read, and a segment being recorded
as far as written so far; `segment_warnings` names what is read only in part or not at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.middleware.monitor_feed import DESCRIPTION_TYPE, MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_dof, raw_field, raw_sizes
from plem.recording.archive import iso_time
from plem.recording.summary import (
    CYCLE_END,
    EVERYTHING,
    BagError,
    RobotBags,
    SegmentInfo,
    Window,
    last_message,
    read_topic,
    robot_segments,
)

#: Samples kept at most, evenly spaced over the range.
MAX_POINTS = 20_000
RAW_TYPE = MONITOR_TOPICS["rt_raw"]
#: The joint rows kept for the samples picked.
JOINT_ROWS = ("position", "command_position", "velocity")


@dataclass(frozen=True)
class Marker:
    """A fault, its clearing, or a mode change, from rt_events."""

    time_ns: int       # absolute wall-clock ns (the bag's log time)
    kind: str          # "fault" | "fault_cleared" | "mode"
    label: str         # e.g. "fault: following error on joint2 ..." / "hold → trajectory"
    cycle: int


@dataclass(frozen=True)
class Timeline:
    """One robot's recording between two times: decimated samples, every latency, markers and its URDF."""

    robot_id: str
    joint_names: list[str]
    time_ns: np.ndarray            # int64 absolute wall ns per (decimated) sample
    position: np.ndarray           # (N, dof)
    command_position: np.ndarray   # (N, dof)
    velocity: np.ndarray           # (N, dof)
    mode: np.ndarray               # (N,) int mode code (plem.control.modes.Mode values)
    latency_us: np.ndarray         # (N,) wake-up latency of the decimated samples
    all_latency_us: np.ndarray     # every sample's latency in the range (for histograms/percentiles)
    markers: list[Marker]
    description: str | None        # the URDF text recorded with the bags, newest one; None in older bags

    def faults(self) -> list[Marker]:
        """The fault markers, oldest first."""
        return [marker for marker in self.markers if marker.kind == "fault"]


def read_timeline(robot: RobotBags, start_ns: int | None = None, end_ns: int | None = None,
                  max_points: int = MAX_POINTS) -> Timeline:
    """The timeline of a robot's bags from `start_ns` to `end_ns` (ns since the epoch, both included; None: from
    the first or to the last sample); BagError (WHAT/WHY/HOW) when no rt_raw sample is there."""
    return timeline_of(robot.robot_id, robot_segments(robot), start_ns, end_ns, max_points)


def recorded_faults(segments: list[SegmentInfo]) -> list[Marker]:
    """Every fault the segments recorded, oldest first, read from rt_events alone (not the 1 kHz samples)."""
    readable = [segment for segment in segments if segment.readable]
    return [marker for marker in _markers(readable, EVERYTHING) if marker.kind == "fault"]


def extent(segments: list[SegmentInfo]) -> Window | None:
    """The first and last log time of the segments a timeline reads; None when none reads."""
    spans = [(segment.start_ns, segment.start_ns + segment.duration_ns) for segment in segments
             if segment.readable and segment.start_ns is not None and segment.duration_ns is not None]
    return (min(start for start, _ in spans), max(end for _, end in spans)) if spans else None


def segment_warnings(segments: list[SegmentInfo]) -> list[str]:
    """One line per segment a timeline reads only in part (being recorded) or leaves out (killed, damaged)."""
    return [f"{segment.name} is being recorded: read as far as written so far" if segment.readable
            else f"{segment.name} left out: {segment.note()}" for segment in segments if segment.state != "complete"]


def _overlaps(segment: SegmentInfo, window: Window) -> bool:
    """Whether a segment holds messages (as far as its extent tells) within `window`."""
    start, duration = segment.start_ns, segment.duration_ns
    return start is not None and duration is not None and start <= window[1] and start + duration >= window[0]


def _inside(stamps: np.ndarray, window: Window) -> np.ndarray:
    """Indexes of the log times within `window`."""
    return np.flatnonzero((stamps >= window[0]) & (stamps <= window[1]))


def _samples_in(segment: SegmentInfo, topic: str, window: Window) -> int:
    """rt_raw samples of a segment within `window`: all it holds when it lies inside, else counted from log times."""
    start, duration = segment.start_ns or 0, segment.duration_ns or 0
    if window[0] <= start and start + duration <= window[1]:
        return segment.topics[topic][1]
    return sum(len(_inside(payloads.stamps, window))
               for payloads in read_topic(segment.path, topic, head=CYCLE_END, window=window))


def timeline_of(robot_id: str, segments: list[SegmentInfo], start_ns: int | None = None, end_ns: int | None = None,
                max_points: int = MAX_POINTS) -> Timeline:
    """`read_timeline` of segments already listed (`robot_segments`)."""
    window = (max(EVERYTHING[0], start_ns or 0), EVERYTHING[1] if end_ns is None else min(EVERYTHING[1], end_ns))
    overlapping = [segment for segment in segments if segment.readable and _overlaps(segment, window)]
    readable = [(segment, topic) for segment in overlapping if (topic := segment.topic_of(RAW_TYPE))]
    counts = [_samples_in(segment, topic, window) for segment, topic in readable]
    if not sum(counts):
        raise _nothing_there(segments, start_ns, end_ns)
    stride = max(1, -(-sum(counts) // max_points))
    dof: int | None = None
    seen = 0
    latencies: list[np.ndarray] = []
    picked: dict[str, list[np.ndarray]] = {name: [] for name in ("time_ns", "mode", "latency_ns", *JOINT_ROWS)}
    for (segment, topic), left in zip(readable, counts, strict=True):
        for payloads in read_topic(segment.path, topic, window=window):
            inside = _inside(payloads.stamps, window)[:left]    # a segment being recorded: as far as counted
            if not len(inside):
                continue
            left -= len(inside)
            dof = raw_dof(payloads.message(int(inside[0]))) if dof is None else dof
            if np.any(~np.isin(payloads.sizes[inside], raw_sizes(dof))):
                raise BagError(f"rt_raw in {segment.name} does not have {dof} joints throughout",
                               what=f"RtRaw messages of one arm ({dof} joints, as the first one)",
                               why=f"messages of another size in {segment.name}",
                               how="plot the segments of each arm separately (pass one segment directory)")
            latencies.append(raw_field(payloads.buffer, payloads.starts[inside], "latency_ns"))
            pick = inside[-seen % stride::stride]
            picked["time_ns"].append(payloads.stamps[pick])
            for name in ("mode", "latency_ns"):
                picked[name].append(raw_field(payloads.buffer, payloads.starts[pick], name))
            for name in JOINT_ROWS:
                picked[name].append(raw_field(payloads.buffer, payloads.starts[pick], name, dof))
            seen += len(inside)
    assert dof is not None                                   # the counts found samples
    columns = {name: np.concatenate(parts) for name, parts in picked.items()}
    found = last_message(overlapping, DESCRIPTION_TYPE)
    return Timeline(robot_id, _joint_names(overlapping, dof), columns["time_ns"].astype(np.int64),
                    columns["position"], columns["command_position"], columns["velocity"],
                    columns["mode"].astype(np.int64), columns["latency_ns"] / 1e3, np.concatenate(latencies) / 1e3,
                    _markers(overlapping, window), None if found is None else _string(found[1]))


def _nothing_there(segments: list[SegmentInfo], start_ns: int | None, end_ns: int | None) -> BagError:
    """No rt_raw sample at all, or none in the range asked for (then the recording's extent says where to look)."""
    span = extent([segment for segment in segments if segment.topic_of(RAW_TYPE)])
    if (start_ns is None and end_ns is None) or span is None:
        readable = sum(segment.readable and segment.topic_of(RAW_TYPE) is not None for segment in segments)
        return BagError("no rt_raw samples in the bags", what=f"complete segments with {RAW_TYPE} messages",
                        why=f"{readable} of {len(segments)} segments are complete (or being recorded) and have an "
                            "rt_raw topic, holding no messages",
                        how="repair killed segments with `plem bag repair DIR`, or pass a directory the recorder "
                            "wrote while the robot ran")
    bounds = [f"{word} {iso_time(ns)}" for word, ns in (("from", start_ns), ("to", end_ns)) if ns is not None]
    return BagError(f"no rt_raw samples {' '.join(bounds)}",
                    what="a time range within the recording",
                    why=f"the recording covers {iso_time(span[0])} to {iso_time(span[1])}",
                    how="pass --from/--to within it: ISO or clock times (UTC), or +SECONDS after its start")


def _string(payload: bytes) -> str:
    """The text of a std_msgs/msg/String payload."""
    from plem.middleware.types import library

    message: Any = library().store.deserialize_cdr(payload, DESCRIPTION_TYPE)   # a generated message
    return str(message.data)


def _joint_names(segments: list[SegmentInfo], dof: int) -> list[str]:
    """The names in the first joint_states message when they fit the DOF, else joint0..N."""
    from plem.middleware.types import library

    ros_type = MONITOR_TOPICS["joint_states"]
    for segment in segments:
        topic = segment.topic_of(ros_type)
        first = next(read_topic(segment.path, topic), None) if topic else None
        if first is not None:
            message: Any = library().store.deserialize_cdr(first.message(0), ros_type)  # a generated message
            names = list(message.name)
            if len(names) == dof:
                return names
            break
    return [f"joint{index}" for index in range(dof)]


def _markers(segments: list[SegmentInfo], window: Window) -> list[Marker]:
    """Faults, fault clearings and mode changes within `window`, oldest first."""
    from plem.middleware.types import library

    ros_type = MONITOR_TOPICS["rt_events"]
    store = library().store
    markers = []
    for segment in segments:
        topic = segment.topic_of(ros_type)
        for payloads in read_topic(segment.path, topic, window=window) if topic else ():
            for index in _inside(payloads.stamps, window):
                event: Any = store.deserialize_cdr(payloads.message(int(index)), ros_type)  # a generated message
                marker = _marker(int(payloads.stamps[index]), event)
                if marker is not None:
                    markers.append(marker)
    return sorted(markers, key=lambda marker: marker.time_ns)


def _marker(time_ns: int, event: Any) -> Marker | None:
    """The marker of one RtEvent; None for the kinds not marked (motions, rejected commands, warnings)."""
    if event.kind == "fault":
        return Marker(time_ns, "fault", f"fault: {event.reason or event.cause}", int(event.cycle))
    if event.kind == "fault_cleared":
        return Marker(time_ns, "fault_cleared", f"fault cleared: {event.reason or event.cause}", int(event.cycle))
    if event.kind == "mode_changed":
        return Marker(time_ns, "mode", f"{event.previous_mode} → {event.mode}", int(event.cycle))
    return None
