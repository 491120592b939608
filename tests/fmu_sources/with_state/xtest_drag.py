"""Test FMU (third-party style): a speed under quadratic drag, v' = u - c v |v|, integrated
over each step by 16 RK4 substeps for the u held over it (nonlinear: its response to u
depends on v); its output v does not depend on the current u (the test declares that in the
model description, as a C exporter would)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

SUBSTEPS = 16


class XtestDrag(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "v' = u - c v |v|"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.c, self.u, self.v = 1.0, 0.0, 0.0
        self.register_variable(Real("c", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("v", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def _rate(self, v):
        return self.u - self.c * v * abs(v)

    def do_step(self, current_time, step_size):
        dt = step_size / SUBSTEPS
        v = self.v
        for _ in range(SUBSTEPS):
            k1 = self._rate(v)
            k2 = self._rate(v + 0.5 * dt * k1)
            k3 = self._rate(v + 0.5 * dt * k2)
            k4 = self._rate(v + dt * k3)
            v += dt * (k1 + 2 * k2 + 2 * k3 + k4) / 6
        self.v = v
        return True
