"""Test FMU (third-party style): two integrators in a row, v' = u, x' = v, exact for u held
over a step; its output x does not depend on the current u (the test declares that in the
model description, as a C exporter would). Its response to a held input is of second order."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestDouble(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x'' = u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u, self.v, self.x = 0.0, 0.0, 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("v", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        self.x += self.v * step_size + 0.5 * self.u * step_size * step_size
        self.v += self.u * step_size
        return True
