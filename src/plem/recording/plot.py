"""One robot's timeline as a figure: joint positions (measured solid with a marker of its own, commanded dashed,
one colour per joint), velocities and the loop's wake-up latency over absolute time (UTC), with the modes as
shaded bands and the faults as labelled lines (labels clipped to their panel), and the latency histogram with
its percentiles; `render` makes it a PNG.

Legends sit right of the axes, never over the data; the modes' legend, which holds for every panel over time,
sits under the title. Every artist drawn from the timeline has a gid for tests to find: measured:<joint>,
commanded:<joint>, velocity:<joint>, mode:<mode>, fault, fault_label, latency, latency_histogram,
percentile:<name>.
"""

from __future__ import annotations

import datetime as dt
import io
from typing import TYPE_CHECKING, Any

import numpy as np

from plem.control.modes import Mode
from plem.recording.archive import iso_time
from plem.recording.timeline import Timeline

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.collections import Collection
    from matplotlib.figure import Figure

#: Figure size in inches at `DPI`: the PNG is 1400 × 1200 pixels.
SIZE, DPI = (14.0, 12.0), 100
PERCENTILES = (("p50", 50.0), ("p99", 99.0), ("p99.9", 99.9))
#: Band colour of each mode; a code plem does not know is grey.
MODE_COLORS = {"idle": "tab:gray", "hold": "tab:blue", "trajectory": "tab:green", "free_drive": "tab:purple",
               "fault": "tab:red"}
BAND_ALPHA = 0.12
FAULT_COLOR = "crimson"
#: Characters of a fault's reason shown next to its line (clipped to the panel beyond that).
LABEL_CHARS = 60
#: Each joint's marker, placed every `MARKS` samples at an offset of its own, so that joints on the same path stay
#: visible (and told apart) where their lines coincide.
MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")
MARKS = 12


def mode_name(code: int) -> str:
    """'hold', 'trajectory', ... for a recorded mode code; 'mode N' for one plem does not know."""
    try:
        return str(Mode(code))
    except ValueError:
        return f"mode {code}"


def _legend(axes: Axes, **options: Any) -> None:
    """The axes' legend right of them, outside the data."""
    axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small", **options)


def _dates(time_ns: np.ndarray) -> np.ndarray:
    """matplotlib date numbers (days since its epoch) of absolute ns."""
    from matplotlib.dates import date2num

    days = date2num(np.asarray(time_ns, dtype="datetime64[ns]"))  # type: ignore[no-untyped-call]  # untyped
    return np.asarray(days)


def _mode_bands(axes: Axes, x: np.ndarray, modes: np.ndarray) -> dict[str, Collection]:
    """One shaded band per run of a mode, each from its first sample to the next run's; the collection per mode."""
    from matplotlib.collections import PolyCollection

    changes = np.flatnonzero(np.diff(modes)) + 1
    starts = np.concatenate([[0], changes])
    ends = np.concatenate([changes, [len(modes) - 1]])
    bands = {}
    for code in np.unique(modes):
        runs = np.flatnonzero(modes[starts] == code)
        name = mode_name(int(code))
        bands[name] = axes.add_collection(PolyCollection(
            [[(left, 0), (left, 1), (right, 1), (right, 0)] for left, right in zip(x[starts[runs]], x[ends[runs]],
                                                                                   strict=True)],
            transform=axes.get_xaxis_transform(), facecolor=MODE_COLORS.get(name, "0.5"), edgecolor="none",
            alpha=BAND_ALPHA, gid=f"mode:{name}", label=name, zorder=0), autolim=False)
    return bands


def figure(timeline: Timeline, title: str) -> Figure:
    """The figure: positions, velocities and latency over time (shared axis), and the latency histogram."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.dates import AutoDateLocator, ConciseDateFormatter
    from matplotlib.figure import Figure
    from matplotlib.legend import Legend
    from matplotlib.lines import Line2D

    figure = Figure(figsize=SIZE, dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    position, velocity, latency, histogram = figure.subplots(4, 1, height_ratios=(3, 2, 2, 2))
    velocity.sharex(position)
    latency.sharex(position)
    figure.suptitle(f"{title}\n{iso_time(int(timeline.time_ns[0]))} to {iso_time(int(timeline.time_ns[-1]))}")
    x = _dates(timeline.time_ns)
    measured = []
    dof = len(timeline.joint_names)
    every = max(1, len(x) // MARKS)
    for index, name in enumerate(timeline.joint_names):
        color = f"C{index % 10}"
        measured += position.plot(x, timeline.position[:, index], color=color, linewidth=0.9, label=name,
                                  gid=f"measured:{name}", marker=MARKERS[index % len(MARKERS)], markersize=4,
                                  markevery=(index * every // dof, every))
        position.plot(x, timeline.command_position[:, index], color=color, linewidth=0.9, linestyle="--",
                      gid=f"commanded:{name}")
        velocity.plot(x, timeline.velocity[:, index], color=color, linewidth=0.8, gid=f"velocity:{name}")
    stride = max(1, round(len(timeline.all_latency_us) / len(timeline.time_ns)))
    buckets = np.linspace(0, len(timeline.all_latency_us), len(timeline.time_ns), endpoint=False).astype(np.int64)
    latency_line = latency.plot(x, np.maximum.reduceat(timeline.all_latency_us, buckets), color="black",
                                linewidth=0.7, gid="latency",
                                label="latency" if stride == 1 else f"max of each ~{stride} cycles")
    faults = timeline.faults()
    at = _dates(np.array([fault.time_ns for fault in faults], dtype=np.int64))
    bands: dict[str, Collection] = {}
    for axes in (position, velocity, latency):
        bands = _mode_bands(axes, x, timeline.mode)          # the same on each: the last ones make the legend
        for fault_x in at:
            axes.axvline(float(fault_x), color=FAULT_COLOR, linewidth=1.2, gid="fault")
        axes.grid(alpha=0.3)
    for fault, fault_x in zip(faults, at, strict=True):
        text = fault.label if len(fault.label) <= LABEL_CHARS else fault.label[:LABEL_CHARS - 1] + "…"
        position.text(float(fault_x), 0.98, f" {text}", transform=position.get_xaxis_transform(), rotation=90,
                      ha="right", va="top", fontsize="small", color=FAULT_COLOR, gid="fault_label", clip_on=True,
                      bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 1})
    locator = AutoDateLocator(tz=dt.UTC)  # type: ignore[no-untyped-call]  # matplotlib.dates is untyped
    position.xaxis.set_major_locator(locator)
    position.xaxis.set_major_formatter(ConciseDateFormatter(locator, tz=dt.UTC))  # type: ignore[no-untyped-call]
    for axes in (position, velocity):
        axes.tick_params(labelbottom=False)
    position.set(ylabel="position (rad)")
    velocity.set(ylabel="velocity (rad/s)")
    latency.set(ylabel="wake-up latency (µs)", xlabel="time (UTC)")
    styles = [Line2D([], [], color="0.3", linewidth=0.9, label="measured"),
              Line2D([], [], color="0.3", linewidth=0.9, linestyle="--", label="commanded")]
    _legend(position, handles=[*measured, *styles])
    fault_line = [Line2D([], [], color=FAULT_COLOR, linewidth=1.2, label="fault event")] if faults else []
    mode_keys = [*bands.values(), *fault_line]
    modes = Legend(position, mode_keys, [str(key.get_label()) for key in mode_keys], loc="lower center",
                   bbox_to_anchor=(0.5, 1.01), borderaxespad=0.0, ncols=len(mode_keys), fontsize="small",
                   title="mode, shaded over the position, velocity and latency panels")
    modes.get_title().set_fontsize("small")
    position.add_artist(modes).set_clip_on(False)     # unclipped: the layout makes room for it above the panel
    _legend(latency, handles=latency_line)
    _histogram(histogram, timeline.all_latency_us)
    return figure


def _histogram(axes: Axes, latency_us: np.ndarray) -> None:
    """Every cycle's wake-up latency, with its percentiles and maximum marked."""
    axes.hist(latency_us, bins=200, log=True, histtype="stepfilled", alpha=0.7, gid="latency_histogram")
    marks = [(name, float(np.percentile(latency_us, q))) for name, q in PERCENTILES]
    for (name, value), color in zip([*marks, ("max", float(latency_us.max()))],
                                    ("tab:green", "tab:orange", "tab:red", "black"), strict=True):
        axes.axvline(value, color=color, linestyle="--", linewidth=1, label=f"{name} {value:.1f} µs",
                     gid=f"percentile:{name}")
    axes.set(xlabel=f"wake-up latency (µs), {len(latency_us)} cycles", ylabel="cycles (log)")
    _legend(axes)


def render(timeline: Timeline, title: str) -> bytes:
    """The figure as PNG bytes."""
    buffer = io.BytesIO()
    figure(timeline, title).savefig(buffer, format="png")
    return buffer.getvalue()
