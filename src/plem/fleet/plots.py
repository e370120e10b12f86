"""Pictures of the fleet reports (matplotlib, Agg: no display needed)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd


def health(report: pd.DataFrame, path: Path) -> None:
    """Per robot over the days: wake-up latency p50/p99/p99.9 (top), overruns and lost frames per day (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (latency, counts) = plt.subplots(2, 1, figsize=(11, 8), sharex=True, height_ratios=(3, 2))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for index, (robot, rows) in enumerate(report.groupby("robot_id", sort=True)):
        colour = colours[index % len(colours)]
        days = [str(day) for day in rows["day"]]
        latency.plot(days, rows["latency_p99_us"].astype(float), color=colour, marker="o", label=robot)
        latency.plot(days, rows["latency_p999_us"].astype(float), color=colour, marker="^", linestyle="--")
        latency.plot(days, rows["latency_p50_us"].astype(float), color=colour, linestyle=":")
        counts.plot(days, rows["overruns"].astype(float), color=colour, marker="o", label=robot)
        counts.plot(days, rows["lost_frames"].astype(float), color=colour, marker="x", linestyle="--")
    latency.set_ylabel("wake-up latency (µs)")
    latency.set_title("Loop wake-up latency per robot and day (p50 dotted, p99 solid, p99.9 dashed)")
    counts.set_ylabel("per day")
    counts.set_title("Overruns (solid) and lost frames (dashed) per robot and day")
    counts.set_xlabel("day (UTC)")
    for axes in (latency, counts):
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), title="robot",
                    ncols=1 + report["robot_id"].nunique() // 16)
    plt.setp(counts.get_xticklabels(), rotation=30, ha="right")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def usage(report: pd.DataFrame, path: Path, top: int = 20) -> None:
    """The `top` most travelled joints (the maintenance order), travel and reversals side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = report.head(top).iloc[::-1]
    labels = [f"{robot} {name or joint}" for robot, joint, name in
              zip(shown["robot_id"], shown["joint"], shown["joint_name"], strict=True)]
    figure, (travel, reversals) = plt.subplots(1, 2, figsize=(11, 0.35 * len(shown) + 1.8), sharey=True)
    travel.barh(labels, shown["travel"])
    travel.set_xlabel("travel Σ|Δposition| (rad or m)")
    reversals.barh(labels, shown["reversals"], color="tab:orange")
    reversals.set_xlabel("reversals")
    figure.suptitle(f"Joints by travel (the {len(shown)} most travelled)")
    for axes in (travel, reversals):
        axes.grid(True, axis="x", alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
