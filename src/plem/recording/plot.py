"""One robot's recorded rt_raw as a PNG: joint positions and velocities over time, and the loop's wake-up latency.

Lines are drawn from at most `MAX_POINTS` evenly spaced samples; the latency histogram and its
percentiles use every sample.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.middleware.monitor_feed import MONITOR_TOPICS
from plem.middleware.raw_cdr import raw_dof, raw_dtype, raw_field
from plem.recording.summary import BagError, SegmentInfo, read_topic

#: Samples per line drawn.
MAX_POINTS = 20_000
#: Figure size in inches at `DPI`: the PNG is 1200 × 1000 pixels.
SIZE, DPI = (12.0, 10.0), 100
PERCENTILES = (("p50", 50.0), ("p99", 99.0), ("p99.9", 99.9))


@dataclass(frozen=True)
class RawSeries:
    """rt_raw of one robot: decimated time (s from the first sample), positions and velocities; every latency (µs)."""

    time_s: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    latency_us: np.ndarray
    joint_names: list[str]


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


def read_raw(segments: list[SegmentInfo]) -> RawSeries:
    """The rt_raw of the complete segments, in order."""
    ros_type = MONITOR_TOPICS["rt_raw"]
    readable = [(segment, topic) for segment in segments
                if segment.state == "complete" and (topic := segment.topic_of(ros_type))]
    total = sum(segment.topics[topic][1] for segment, topic in readable)
    stride = max(1, -(-total // MAX_POINTS))
    dof: int | None = None
    seen = 0
    stamps, positions, velocities, latencies = [], [], [], []
    for segment, topic in readable:
        for payloads in read_topic(segment.path, topic):
            dof = raw_dof(payloads.message(0)) if dof is None else dof
            if np.any(payloads.sizes != raw_dtype(dof).itemsize):
                raise BagError(f"rt_raw in {segment.name} does not have {dof} joints throughout",
                               what=f"RtRaw messages of one arm ({dof} joints, as the first one)",
                               why=f"messages of another size in {segment.name}",
                               how="plot the segments of each arm separately (pass one segment directory)")
            latencies.append(raw_field(payloads.buffer, payloads.starts, "latency_ns"))
            pick = np.arange(-seen % stride, len(payloads.starts), stride)
            stamps.append(payloads.stamps[pick])
            positions.append(raw_field(payloads.buffer, payloads.starts[pick], "position", dof))
            velocities.append(raw_field(payloads.buffer, payloads.starts[pick], "velocity", dof))
            seen += len(payloads.starts)
    if dof is None:
        raise BagError("no rt_raw samples in the bags", what=f"complete segments with {ros_type} messages",
                       why=f"{len(readable)} of {len(segments)} segments are complete and have an rt_raw topic, "
                           "holding no messages",
                       how="repair killed segments with `plem bag repair DIR`, or pass a directory the recorder "
                           "wrote while the robot ran")
    time_ns = np.concatenate(stamps)
    return RawSeries((time_ns - time_ns[0]) / 1e9, np.concatenate(positions), np.concatenate(velocities),
                     np.concatenate(latencies) / 1e3, _joint_names([segment for segment, _ in readable], dof))


def render(series: RawSeries, title: str) -> bytes:
    """The PNG: positions, velocities, and the latency histogram with its percentiles and maximum marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=SIZE, dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    position, velocity, latency = figure.subplots(3, 1)
    figure.suptitle(title)
    for axes, values, label in ((position, series.position, "position (rad)"),
                                (velocity, series.velocity, "velocity (rad/s)")):
        for index, name in enumerate(series.joint_names):
            axes.plot(series.time_s, values[:, index], linewidth=0.8, label=name)
        axes.set(xlabel="time (s)", ylabel=label)
        axes.grid(alpha=0.3)
    position.legend(loc="upper right", ncols=len(series.joint_names), fontsize="small")
    latency.hist(series.latency_us, bins=200, log=True, histtype="stepfilled", alpha=0.7)
    marks = [(name, float(np.percentile(series.latency_us, q))) for name, q in PERCENTILES]
    for (name, value), color in zip([*marks, ("max", float(series.latency_us.max()))],
                                    ("tab:green", "tab:orange", "tab:red", "black"), strict=True):
        latency.axvline(value, color=color, linestyle="--", linewidth=1, label=f"{name} {value:.1f} µs")
    latency.set(xlabel=f"wake-up latency (µs), {len(series.latency_us)} cycles", ylabel="cycles (log)")
    latency.legend(loc="upper right")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()
