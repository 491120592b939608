"""Simulation results: a structured array whose first field is `time`, plus metadata."""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np


BELOW_ROUND_OFF = "below round-off"    # an error estimate within the outputs' round-off
_ROUND_OFF = 8 * np.finfo(float).eps    # per step, relative to the output's size
CANCELS = 0.1   # an error estimate under this share of the size of the terms it sums


def cancelled(detail: str = "") -> str:
    """The words of an error estimate under CANCELS of its terms' size: unresolved (what is
    left of terms that cancel; the terms are estimates, good to a few tens of percent)."""
    return (f"unresolved (its error is what is left of terms that cancel to under {CANCELS:g} "
            f"of their sum{detail})")


def round_off(values, steps: int) -> float:
    """The round-off an output can gather in `steps` steps: 8 eps per step, relative to its
    largest size (at least 1). An error estimate at or below it is BELOW_ROUND_OFF."""
    scale = max(1.0, float(np.max(np.abs(values)))) if len(values) else 1.0
    return float(_ROUND_OFF * scale * max(steps, 1))


@dataclass
class Results:
    names: tuple[str, ...]          # recorded `instance.variable`, in column order
    data: np.ndarray                # structured: ('time', f8) then one field per name
    master: str
    start_time: float
    stop_time: float
    step_size: float
    steps: int                      # communication steps completed
    wall_time: float                # seconds spent in the stepping loop
    complete: bool = True
    extra: dict = field(default_factory=dict)
    steps_taken: int | None = None      # the adaptive master: accepted steps (doStep passes)
    steps_rejected: int = 0             # ... and rejected ones, rolled back

    @property
    def time(self) -> np.ndarray:
        return self.data["time"]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name]

    def final(self, name: str) -> float:
        return float(self.data[name][-1])

    @property
    def ended_by(self) -> str | None:
        """Where an FMU asked to end the simulation before the stop time (extra["ended"],
        master._ended): who, how, and the time of the last row; else None."""
        ended = self.extra.get("ended")
        return None if ended is None else (
            f"{ended['by']} asked to end the simulation ({ended['how']}); the run ends at "
            f"t = {ended['time']:g} s, its last row, complete there as the FMI standard has it")


def csv_writer(fh, names: tuple[str, ...]):
    """A CSV writer on fh with the header written: `time`, then the recorded names."""
    writer = csv.writer(fh, lineterminator="\n")
    writer.writerow(("time",) + tuple(names))
    return writer


def write_rows(writer, data: np.ndarray) -> None:
    """The rows of a structured array (fields: time, then the names), as results.csv holds them."""
    columns = [data[n] for n in data.dtype.names]
    for row in zip(*(c.tolist() for c in columns)):
        writer.writerow([format_value(v) for v in row])


def format_value(value) -> str:
    """One value as results.csv (and runs.csv) writes it: repr keeps a float exact."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def error_estimate_lines(summary: dict) -> list[str]:
    """summary.json's error estimate (master/estimate.py) as the run's report prints it."""
    if "error_estimate_method" not in summary:
        return []
    estimate = summary["error_estimate"]
    if estimate is None:
        return [f"error estimate: {summary['error_estimate_method']}"]
    lines = [f"error estimate ({summary['error_estimate_method']}):"]
    if "steps_taken" in summary:
        lines.insert(0, f"tolerance {summary['tolerance']:g}: {summary['steps_taken']} steps "
                        f"taken, {summary['steps_rejected']} rejected and rolled back")
    for name, e in estimate.items():
        lines.append(f"  {name}: max and end {e['max']}" if isinstance(e["max"], str)
                     and e["max"] == e["end"] else
                     f"  {name}: max {_show(e['max'])}, end {_show(e['end'])}")
    return lines + [f"advice: {said}" for said in summary.get("error_estimate_advice", ())]


def _show(value) -> str:
    return value if isinstance(value, str) else f"{value:.2e}"
