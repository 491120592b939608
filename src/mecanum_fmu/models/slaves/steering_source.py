"""SteeringSource FMU: the car-like robot's command, speed v and steering angle phi, as expressions of t."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.expression import ExpressionError, compile_expression  # inline

_OUTPUTS = ("v", "phi")
_EXPRESSIONS = ("v_expr", "phi_expr")


class SteeringSource(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Commanded speed v and steering angle phi (positive turns left) of a car-like "
                   "robot as expressions of t, evaluated safely like VelocitySource's (numbers, t, "
                   "arithmetic, comparisons, sin cos tan asin acos atan atan2 sinh cosh tanh exp "
                   "log sqrt abs min max floor ceil clip where, pi, e). Defaults: v = 1, phi = 0.2.")
    UNITS = {"v": "m/s", "phi": "rad"}
    DEPENDENCIES = {name: () for name in _OUTPUTS}
    INITIAL_DEPENDENCIES = dict(zip(_OUTPUTS, ((e,) for e in _EXPRESSIONS)))
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.v_expr, self.phi_expr = "1", "0.2"
        self.v = self.phi = 0.0
        self._start_time = 0.0
        self._profile = None
        docs = {"v_expr": "v(t) [m/s], rear-axle speed, positive forward",
                "phi_expr": "phi(t) [rad], steering angle, positive turns left"}
        for name in _EXPRESSIONS:
            self.register_variable(String(name, causality=Fmi2Causality.parameter,
                                          variability=Fmi2Variability.fixed,
                                          description=docs[name]))
        out_docs = {"v": "commanded rear-axle speed, positive forward",
                    "phi": "commanded steering angle, positive turns left (counter-clockwise)"}
        for name in _OUTPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=out_docs[name]))

    def _evaluate(self, t):
        try:
            self.v, self.phi = (f(t) for f in self._profile)
        except ExpressionError as err:
            self.log(f"SteeringSource: {err}", Fmi2Status.error)
            raise

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = start_time

    def enter_initialization_mode(self):
        # Compile here (not per step): a bad expression is reported at initialization.
        try:
            self._profile = tuple(compile_expression(getattr(self, name))
                                  for name in _EXPRESSIONS)
        except ExpressionError as err:
            self.log(f"SteeringSource: {err}", Fmi2Status.error)
            raise
        self._evaluate(self._start_time)

    def exit_initialization_mode(self):
        self.enter_initialization_mode()  # parameters may have changed during initialization

    def do_step(self, current_time, step_size):
        self._evaluate(current_time + step_size)
        return True
