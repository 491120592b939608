"""A run held against a recorded pose: the scenario's `recorded: {pose: {file: day1, topic:
/odom}}` (a bag's Odometry or PoseStamped, or a CSV path; profiles.recorded_paths) compared with
the simulated pose at each of the run's times inside the recording (the recording read there
linearly, as a table is).

- `compare(results, recorded)`: per pose, the position error |(x, y)_sim - (x, y)_rec| [m]
  (max, rms, at the last recorded time) and, when the recording has a heading, the heading
  error wrapped to (-pi, pi] [rad]: summary.json's `against_recorded`.
- `write_figure(...)`: recorded.png, "recorded against simulated": both paths, and the
  position error against time.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..models.blocks.profile_table import PATH_COLUMNS, parse_table
from ..results import Results

TITLE = "Recorded against simulated"


def recorded_rows(text: str) -> dict[str, np.ndarray]:
    """time, x, y (and theta when recorded) of a checked path table."""
    columns = parse_table(text, PATH_COLUMNS, ("theta",), True)
    return {name: np.asarray(col, dtype=float)
            for name, col in zip(PATH_COLUMNS, columns) if col is not None}


def position_errors(results: Results, pose: str, rec: dict[str, np.ndarray]) -> dict | None:
    """The recording at the run's times inside it (linear, as a table is read), and the
    errors of the simulated pose there."""
    t = np.asarray(results.time, dtype=float)
    inside = (t >= rec["time"][0]) & (t <= rec["time"][-1])
    if not inside.any():
        return None
    at = t[inside]
    sim = {k: np.asarray(results[f"{pose}.{k}"], dtype=float)[inside] for k in ("x", "y", "theta")}
    ref = {k: np.interp(at, rec["time"], rec[k]) for k in ("x", "y", "theta") if k in rec}
    out = {"time": at, "position": np.hypot(sim["x"] - ref["x"], sim["y"] - ref["y"])}
    if "theta" in ref:
        out["heading"] = np.angle(np.exp(1j * (sim["theta"] - ref["theta"])))
    return out


def _figures(err: np.ndarray) -> dict[str, float]:
    return {"max": float(np.max(np.abs(err))), "rms": float(np.sqrt(np.mean(err ** 2))),
            "end": float(err[-1])}


def compare(results: Results, recorded: dict[str, str]) -> dict:
    """summary.json's `against_recorded`: per pose, the samples compared and the errors."""
    out = {}
    for pose, text in recorded.items():
        if f"{pose}.x" not in results.names or not len(results.time):
            continue
        errors = position_errors(results, pose, recorded_rows(text))
        if errors is None:
            out[pose] = {"samples": 0, "note": "no recorded time inside the run"}
            continue
        entry = {"samples": int(len(errors["time"])), "from": float(errors["time"][0]),
                 "to": float(errors["time"][-1]), "position_error_m": _figures(errors["position"])}
        if "heading" in errors:
            entry["heading_error_rad"] = _figures(errors["heading"])
        out[pose] = entry
    return out


def report_lines(against: dict) -> list[str]:
    return [f"{pose} against the recording: |e| max {e['position_error_m']['max']:.3e} m, "
            f"rms {e['position_error_m']['rms']:.3e} m, end {e['position_error_m']['end']:.3e} m"
            f" ({e['samples']} samples)" for pose, e in against.items() if e["samples"]]


def write_figure(results: Results, recorded: dict[str, str], path: Path) -> Path:
    """recorded.png: per pose, the recorded and the simulated path, and the position error."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    ax_path, ax_err = fig.subplots(1, 2)
    for pose, text in recorded.items():
        rec = recorded_rows(text)
        ax_path.plot(rec["x"], rec["y"], "--", lw=2.5, alpha=0.6, label=f"{pose}: recorded")
        ax_path.plot(results[f"{pose}.x"], results[f"{pose}.y"], lw=1.2,
                     label=f"{pose}: simulated")
        errors = position_errors(results, pose, rec)
        if errors is not None:
            ax_err.plot(errors["time"], np.maximum(errors["position"], 1e-12), label=pose)
    ax_path.set(xlabel="X [m] (right)", ylabel="Y [m] (forward)", title="Paths")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_err.set(xlabel="t [s]", ylabel="|position error| [m]", yscale="log",
               title="Simulated minus recorded")
    for ax in (ax_path, ax_err):
        ax.grid(True)
        ax.legend()
    fig.suptitle(TITLE)
    fig.savefig(path, dpi=100, format="png")
    return path
