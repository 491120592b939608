"""VelocitySource FMU: the commanded chassis twist as three expressions of time, or a table."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.expression import ExpressionError, compile_expression  # inline
from mecanum_fmu.models.blocks.profile_table import TableError, table_sampler  # inline

_OUTPUTS = ("vx", "vy", "w")
_EXPRESSIONS = ("vx_expr", "vy_expr", "w_expr")


class VelocitySource(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Commanded body-frame chassis twist (vx right, vy forward, w counter-clockwise) "
                   "as expressions of t, evaluated safely (numbers, t, arithmetic, comparisons, "
                   "sin cos tan asin acos atan atan2 sinh cosh tanh exp log sqrt abs min max floor "
                   "ceil where, pi, e). Defaults: the seed study, vx = sin(t), vy = cos(t), w = 0. "
                   "A non-empty table (CSV text, header time,vx,vy,w) replaces the expressions.")
    UNITS = {"vx": "m/s", "vy": "m/s", "w": "rad/s"}
    DEPENDENCIES = {name: () for name in _OUTPUTS}
    INITIAL_DEPENDENCIES = dict(zip(_OUTPUTS, ((e, "table", "interpolation") for e in _EXPRESSIONS)))
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vx_expr, self.vy_expr, self.w_expr = "sin(t)", "cos(t)", "0"
        self.vx = self.vy = self.w = 0.0
        self._start_time = 0.0
        self._profile = None
        self._parsed = None          # (table, interpolation) the profile was built from
        docs = {"vx_expr": "vx(t) [m/s], body +X (right)",
                "vy_expr": "vy(t) [m/s], body +Y (forward)",
                "w_expr": "w(t) [rad/s], counter-clockwise"}
        for name in _EXPRESSIONS:
            self.register_variable(String(name, causality=Fmi2Causality.parameter,
                                          variability=Fmi2Variability.fixed,
                                          description=docs[name]))
        out_docs = {"vx": "commanded velocity along body +X (right)",
                    "vy": "commanded velocity along body +Y (forward)",
                    "w": "commanded yaw rate, counter-clockwise positive"}
        for name in _OUTPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=out_docs[name]))
        # Added after the outputs: the value references of the variables above stay as they were.
        self.table, self.interpolation = "", "linear"
        self.register_variable(String("table", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed,
                                      description="CSV text (header time,vx,vy,w; SI units); "
                                                  "when not empty it replaces the expressions"))
        self.register_variable(String("interpolation", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed,
                                      description="between table rows: linear or hold"))

    def _evaluate(self, t):
        try:
            self.vx, self.vy, self.w = (f(t) for f in self._profile)
        except ExpressionError as err:
            self.log(f"VelocitySource: {err}", Fmi2Status.error)
            raise

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = start_time

    def enter_initialization_mode(self):
        # Compile here (not per step): a bad expression is reported at initialization.
        try:
            if self.table and self._parsed == (self.table, self.interpolation):
                pass                 # parsed at enter_initialization_mode: a large table once
            elif self.table:
                sampler = table_sampler(self.table, self.interpolation)
                self._profile = tuple((lambda t, i=i: sampler(t)[i]) for i in range(3))
                self._parsed = (self.table, self.interpolation)
            else:
                self._profile = tuple(compile_expression(getattr(self, name))
                                      for name in _EXPRESSIONS)
        except (ExpressionError, TableError) as err:
            self.log(f"VelocitySource: {err}", Fmi2Status.error)
            raise
        self._evaluate(self._start_time)

    def exit_initialization_mode(self):
        self.enter_initialization_mode()  # parameters may have changed during initialization

    def do_step(self, current_time, step_size):
        self._evaluate(current_time + step_size)
        return True
