"""The estimate's cost as a fixed part and a part per step (bench/estimates.py,
bench/third_party.py): a line through the runs of one scenario (or graph) and master at
different steps, against the run's own stepping per step, and the run length from which the
estimate costs at most BUDGET of the stepping: the fixed part over BUDGET x a step's stepping
less the estimate's own part per step (never, where that part alone is over it)."""
from __future__ import annotations

import math

import numpy as np

BUDGET = 0.2        # the issue's: the estimate at most 0.2x the run's stepping time


def fit(steps, estimate, stepping) -> tuple[float, float, float, float]:
    """(fixed, per step, the run's stepping per step, the steps from which the estimate costs
    at most BUDGET of the stepping; inf: never), in seconds, from runs of `steps` steps whose
    estimate and stepping took `estimate` and `stepping` seconds."""
    n = np.asarray(steps, dtype=float)
    per_step, fixed = np.polyfit(n, np.asarray(estimate, dtype=float), 1)
    step = float(np.median(np.asarray(stepping, dtype=float) / n))
    room = BUDGET * step - per_step
    return float(fixed), float(per_step), step, float(fixed) / room if room > 0 else math.inf


def summary(found: list[tuple], what: str) -> str:
    """One line over fit()'s results, `what` naming the estimate and the runs fitted."""
    fixed, per_step, step, reach = (np.array(v) for v in zip(*found))
    return (f"{what}, a line through each one's steps over {len(found)}: fixed "
            f"{np.median(fixed) * 1e3:.2f} ms median ({fixed.min() * 1e3:.2f} to "
            f"{fixed.max() * 1e3:.2f}), per step {np.median(per_step) * 1e6:.2f} us median "
            f"({per_step.min() * 1e6:.2f} to {per_step.max() * 1e6:.2f}), against the run's "
            f"{np.median(step) * 1e6:.0f} us per step of stepping; at most {BUDGET:g}x of "
            f"the stepping from {np.median(reach):.0f} steps median, "
            f"{reach[np.isfinite(reach)].max(initial=0):.0f} at most, never on "
            f"{int(np.isinf(reach).sum())}")
