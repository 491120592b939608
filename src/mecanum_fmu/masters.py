"""The registry of masters: what each one does, in one place (docs/masters.md).

A master is one entry here; the rest of the code asks the entry (how it holds inputs, whether
it freezes them, whether it rolls back, its order) and never compares a master's name. Plain
data, importable without the FMI runtime (the scenario loader and `validate` use it).
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import Problem, ScenarioError


@dataclass(frozen=True)
class Master:
    name: str
    hold: str               # how inputs are held over a step: "zoh", "trapezoidal", "quadratic"
    freezes_inputs: bool    # every component steps on the values of t_k (Jacobi)
    rolls_back: bool        # a feedback loop is predicted, rolled back and corrected
    order: int              # global order of the end point on smooth inputs (at best)
    doc: str                # one line for --help and the docs
    adaptive: bool = False  # the step is chosen to meet a tolerance (--tolerance)
    # h k below which a follower's loop x' = -k x, closed through the integrator, is stable
    # at step h (plausibility.py warns at and above it; None: no limit stated), stepped in one
    # pass and, for a master that rolls back, rolled back (tests/test_plausibility.py)
    loop_limit: float | None = None
    rolled_back_loop_limit: float | None = None
    # a discrete output (a sensor's sample) is read by an FMU with a continuous output at its
    # value at the step's start, the value it holds over the step (Graph.held); after it
    # changes, the outputs are read again with the new sample (stepping.settle) and the
    # holds' history moves by the jump they made (docs/masters.md, "Samples")
    holds_samples: bool = False


# The loop limits, measured on track_circle with a fixed reference and no heading error: the
# extrapolated single pass decays at h k = 0.95 and grows at 1.05; the quadratic master's
# predictor-corrector at 1.99 / 2.01 (a trapezoidal corrector on the extrapolated predictor
# has its root at z = 1 for h k = 2); Gauss-Seidel's zero-order hold is forward Euler
# (1 - h k: 2); Jacobi delays each of the loop's four components by a step, x' = -k x
# becomes z^4 - z^3 + h k, whose roots leave the unit circle at h k = 0.445 (decays at 0.4,
# grows at 0.5). A large heading error couples in and lowers them.
REGISTRY: dict[str, Master] = {m.name: m for m in (
    Master("quadratic", "quadratic", False, True, 3,
           "Gauss-Seidel order; state-only inputs held at the limited parabola's mean; "
           "loops predicted, rolled back and corrected; samples held from the step's start",
           loop_limit=1.0, rolled_back_loop_limit=2.0, holds_samples=True),
    Master("trapezoidal", "trapezoidal", False, False, 2,
           "Gauss-Seidel order; state-only inputs held at the mean of the step's end values; "
           "samples held from the step's start", loop_limit=1.0, holds_samples=True),
    Master("gauss-seidel", "zoh", False, False, 1,
           "dependency order, zero-order hold of the newest values", loop_limit=2.0),
    Master("jacobi", "zoh", True, False, 1,
           "every component steps on the values of t_k, zero-order hold", loop_limit=0.445),
    Master("adaptive", "quadratic", False, True, 3,
           "a cubic hold (where smooth) on a step chosen to meet a tolerance (--tolerance)",
           adaptive=True),
)}
MASTERS = tuple(REGISTRY)
DEFAULT = "quadratic"
ADAPTIVE = "adaptive"   # what a tolerance chooses (--tolerance, experiment.tolerance)
DEFAULT_TOLERANCE = 1e-4  # the adaptive master's, when neither --tolerance nor the scenario sets one
# the adaptive master's relative tolerance (--relative-tolerance, experiment.relative_tolerance):
# an output's error e is held to e / (tolerance + relative_tolerance |y|) <= 1. 0: the
# tolerance alone, in each output's own unit, as before there was a relative one
DEFAULT_RELATIVE_TOLERANCE = 0.0
ZOH_HOST = "jacobi"     # the master that steps as a plain fixed-step host does (cross-check)
# How a run's error is estimated (--estimate, experiment.estimate; docs/masters.md, "The error
# estimate"): "auto" is the master's own way (for a fixed step the embedded pair, from the
# run's own values, and Richardson where the pair does not apply; the adaptive master's
# per-step errors), "richardson" asks for Richardson by name (a fixed step only), "none"
# turns the estimate off
ESTIMATES = {"auto": "the fixed-step masters: the embedded pair from the run's own values "
                     "(Richardson where it does not apply); the adaptive master: its own",
             "richardson": "the run repeated at two coarser steps (fixed-step masters); "
                           "where FMUs sample at their own period, at half the step",
             "none": "no estimate (summary.json says why)"}
DEFAULT_ESTIMATE = "auto"


def entry(name: str) -> Master:
    """The registry entry of a master name (checked by the scenario loader)."""
    return REGISTRY[name]


def tolerance_master(name: str | None, tolerance: float | None, label: str) -> str | None:
    """The master a command-line --tolerance chooses (None without one): the adaptive one;
    a fixed-step --master beside it is refused."""
    if tolerance is None:
        return None
    if name is not None and not entry(name).adaptive if name in REGISTRY else False:
        raise ScenarioError([Problem(label, "--tolerance", f"the {name} master takes a fixed "
                                     f"step; drop --master {name} (a tolerance chooses the "
                                     f"{ADAPTIVE} master) or --tolerance")])
    return ADAPTIVE
