"""The drift study's table and plot (docs/robot.md, The drift study), from the runs.csv of

    .venv/bin/python -m mecanum_fmu sweep scenarios/sweeps/belief_drift.yaml

    .venv/bin/python docs/drift_study.py results/belief_drift/runs.csv [docs/img/belief_drift.png]

The end drift of a run is its belief (odom) minus its true pose (pose) at the end. Per heading
source (the grid) it prints the distribution of the position and heading drift, and for each
drawn factor the rank correlation (Spearman) of the drift with it: which error the drift follows.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mecanum_fmu.report.plots import new_figure  # noqa: E402

ENCODERS = ("enc1", "enc2", "enc3", "enc4")


def read_runs(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["status"] == "ok"]
    names = rows[0].keys()
    return {n: np.array([r[n] for r in rows], dtype=object if n == "odom.heading" else float)
            for n in names if n not in ("status", "message")}


def drift(runs: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(position drift [m], heading drift [rad]) at the end of each run."""
    position = np.hypot(runs["odom.x"] - runs["pose.x"], runs["odom.y"] - runs["pose.y"])
    dth = runs["odom.theta"] - runs["pose.theta"]
    return position, np.arctan2(np.sin(dth), np.cos(dth))


def factors(runs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The drawn errors, one number per run each."""
    return {
        "encoder noise (mean sigma)": np.mean([runs[f"{e}.sigma"] for e in ENCODERS], axis=0),
        "encoder resolution (least cpr)": np.min([runs[f"{e}.cpr"] for e in ENCODERS], axis=0),
        "gyro noise (sigma)": runs["gyro.sigma"],
        "gyro bias (|bias|)": np.abs(runs["gyro.bias"]),
        # the radius errors that turn the chassis on this circle (docs/sweeps.md): the diagonals
        "wheel radii (|dR1 - dR3| + |dR2 - dR4|)": (np.abs(runs["w2c.dR1"] - runs["w2c.dR3"])
                                                    + np.abs(runs["w2c.dR2"] - runs["w2c.dR4"])),
    }


def table(runs: dict[str, np.ndarray]) -> list[str]:
    position, heading = drift(runs)
    lines = [f"{'heading from':<13}{'runs':>5}  {'position drift [mm]: mean  median   95%    max':<48}"
             f"  heading drift [mrad]: sd   max|.|"]
    for source in ("wheels", "gyro"):
        at = runs["odom.heading"] == source
        p, h = position[at] * 1e3, heading[at] * 1e3
        lines.append(f"{source:<13}{at.sum():>5}  {'':<20}{p.mean():6.1f} {np.median(p):7.1f} "
                     f"{np.percentile(p, 95):6.1f} {p.max():6.1f}{'':<6}{h.std():9.2f} "
                     f"{np.abs(h).max():8.2f}")
    lines.append("")
    lines.append("rank correlation (Spearman) of |heading drift| with each factor:")
    lines.append(f"{'factor':<44}{'wheels':>8}{'gyro':>8}")
    for name, values in factors(runs).items():
        rho = [spearmanr(values[runs["odom.heading"] == s],
                         np.abs(heading[runs["odom.heading"] == s])).statistic
               for s in ("wheels", "gyro")]
        lines.append(f"{name:<44}{rho[0]:8.2f}{rho[1]:8.2f}")
    return lines


def plot(runs: dict[str, np.ndarray], out: Path) -> None:
    position, heading = drift(runs)
    fig = new_figure((12.0, 4.2))
    ax1, ax2, ax3 = fig.subplots(1, 3)
    bins = np.linspace(0, position.max() * 1e3, 30)
    for source, colour in (("wheels", "C0"), ("gyro", "C1")):
        at = runs["odom.heading"] == source
        label = f"heading from {source} (median {np.median(position[at]) * 1e3:.1f} mm)"
        ax1.hist(position[at] * 1e3, bins=bins, alpha=0.6, color=colour, label=label)
        f = factors(runs)
        ax2.plot(f["wheel radii (|dR1 - dR3| + |dR2 - dR4|)"][at] * 1e3, np.abs(heading[at]) * 1e3,
                 ".", color=colour, ms=4, label=f"heading from {source}")
        ax3.plot(f["gyro bias (|bias|)"][at] * 1e3, np.abs(heading[at]) * 1e3, ".", color=colour,
                 ms=4, label=f"heading from {source}")
    ax1.set(xlabel="end position drift |believed - true| [mm]", ylabel="runs",
            title="End drift after the 10 m circle")
    ax2.set(xlabel="|dR1 - dR3| + |dR2 - dR4| [mm]", ylabel="|heading drift| [mrad]",
            title="Heading drift vs the wheels' radii")
    ax3.set(xlabel="|gyro bias| [mrad/s]", ylabel="|heading drift| [mrad]",
            title="Heading drift vs the gyro's bias")
    for ax in (ax1, ax2, ax3):
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    fig.savefig(out)


def main(argv: list[str]) -> int:
    if not argv or len(argv) > 2:
        print("usage: drift_study.py RUNS.csv [PLOT.png]", file=sys.stderr)
        return 2
    try:
        runs = read_runs(Path(argv[0]))
    except (OSError, KeyError, IndexError, ValueError) as err:
        print(f"error: {argv[0]}: not the runs.csv of the belief_drift sweep ({err}); run "
              "`python -m mecanum_fmu sweep scenarios/sweeps/belief_drift.yaml` first",
              file=sys.stderr)
        return 2
    print("\n".join(table(runs)))
    if len(argv) == 2:
        plot(runs, Path(argv[1]))
        print(f"wrote {argv[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
