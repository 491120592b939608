"""PathFollower FMU: measured pose in, body twist out, following a reference path r(t)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.expression import ExpressionError, compile_expression  # inline
from mecanum_fmu.models.blocks.follower import expression_reference, follow  # inline
from mecanum_fmu.models.blocks.profile_table import path_sampler  # inline

_POSE = ("x", "y", "theta")
_TWIST = ("vx", "vy", "w")
_REFS = ("x_ref_expr", "y_ref_expr", "theta_ref_expr")
_GAINS = ("k_pos", "k_theta")


class PathFollower(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Path-following controller for a holonomic chassis: body twist = the "
                   "reference velocity fed forward + k_pos (position error) + k_theta (heading "
                   "error), turned into the body frame (vx right, vy forward, w counter-"
                   "clockwise) with the measured heading. Reference x, y, theta as safe "
                   "expressions of t (rates by central difference), or a recorded path: a "
                   "non-empty table (CSV text, header time,x,y[,theta]) replaces the "
                   "expressions (linear between rows, rates the rows' slopes). Direct "
                   "feedthrough from the measured pose.")
    UNITS = {"x": "m", "y": "m", "theta": "rad", "vx": "m/s", "vy": "m/s", "w": "rad/s",
             "k_pos": "1/s", "k_theta": "1/s"}
    DEPENDENCIES = {name: _POSE for name in _TWIST}
    INITIAL_DEPENDENCIES = {name: _POSE + _REFS + _GAINS + ("table",) for name in _TWIST}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = self.y = self.theta = 0.0
        self.x_ref_expr = self.y_ref_expr = self.theta_ref_expr = "0"
        self.k_pos, self.k_theta = 2.0, 2.0
        self.vx = self.vy = self.w = 0.0
        self._time = 0.0
        self._reference = None
        self._parsed = None     # the table text the reference was built from
        pose_docs = {"x": "measured world-frame position x", "y": "measured world-frame position y",
                     "theta": "measured heading, counter-clockwise"}
        for name in _POSE:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=pose_docs[name]))
        ref_docs = {"x_ref_expr": "reference x(t) [m]", "y_ref_expr": "reference y(t) [m]",
                    "theta_ref_expr": "reference heading theta(t) [rad]"}
        for name in _REFS:
            self.register_variable(String(name, causality=Fmi2Causality.parameter,
                                          variability=Fmi2Variability.fixed,
                                          description=ref_docs[name]))
        gain_docs = {"k_pos": "position feedback gain (error decay rate), > 0",
                     "k_theta": "heading feedback gain (error decay rate), > 0"}
        for name in _GAINS:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=gain_docs[name]))
        twist_docs = {"vx": "commanded velocity along body +X (right)",
                      "vy": "commanded velocity along body +Y (forward)",
                      "w": "commanded yaw rate, counter-clockwise positive"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=twist_docs[name]))
        # Added after the outputs: the value references of the variables above stay as they were.
        self.table = ""
        self.register_variable(String("table", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed,
                                      description="reference path, CSV text (header "
                                                  "time,x,y[,theta]; SI units); when not empty "
                                                  "it replaces the expressions"))

    def _update(self):
        # Direct feedthrough: the outputs follow the measured pose at the current time.
        if self._reference is None:
            return
        try:
            self.vx, self.vy, self.w = follow(self._time, self.x, self.y, self.theta,
                                              self._reference, self.k_pos, self.k_theta)
        except (ExpressionError, ArithmeticError) as err:
            self.log(f"PathFollower: {err}", Fmi2Status.error)
            raise

    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        self._update()

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._time = start_time

    def enter_initialization_mode(self):
        try:
            for name in _GAINS:
                value = getattr(self, name)
                if not (math.isfinite(value) and value > 0.0):
                    raise ValueError(f"parameter {name} = {value!r} 1/s must be > 0")
            if self.table and self._parsed == self.table:
                pass            # parsed at enter_initialization_mode: a large table once
            elif self.table:
                self._reference = path_sampler(self.table)
                self._parsed = self.table
            else:
                self._reference = expression_reference(
                    tuple(compile_expression(getattr(self, name)) for name in _REFS))
        except ValueError as err:      # ExpressionError and TableError are ValueErrors
            self.log(f"PathFollower: {err}", Fmi2Status.error)
            raise
        self._update()

    def exit_initialization_mode(self):
        self.enter_initialization_mode()   # parameters may have changed during initialization

    def do_step(self, current_time, step_size):
        self._time = current_time + step_size
        self._update()
        return True
