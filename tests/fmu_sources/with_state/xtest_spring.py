"""Test FMU (third-party style): a mass on a spring with a damper, x' = v,
v' = (u - k x - c v + mu (1 - x^2) v) / m, integrated over each step by 16 RK4 substeps for
the u held over it; its outputs x and v do not depend on the current u (the test declares
that in the model description, as a C exporter would). Its response to a held input is of second order, two
poles of one step that oscillate (a complex pair) with the defaults; with `mu` (c 0, k 1: a
Van der Pol oscillator) those poles change along the run."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

SUBSTEPS = 16


class XtestSpring(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "m x'' + c x' + k x = u + mu (1 - x^2) x'"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m, self.k, self.c, self.mu = 1.0, 4.0, 0.4, 0.0
        self.u, self.x, self.v = 0.0, 0.0, 0.0
        for name in ("m", "k", "c", "mu"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        for name in ("x", "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))

    def _rate(self, x, v):
        return v, (self.u - self.k * x - self.c * v + self.mu * (1 - x * x) * v) / self.m

    def do_step(self, current_time, step_size):
        dt = step_size / SUBSTEPS
        x, v = self.x, self.v
        for _ in range(SUBSTEPS):
            a1, b1 = self._rate(x, v)
            a2, b2 = self._rate(x + 0.5 * dt * a1, v + 0.5 * dt * b1)
            a3, b3 = self._rate(x + 0.5 * dt * a2, v + 0.5 * dt * b2)
            a4, b4 = self._rate(x + dt * a3, v + dt * b3)
            x += dt * (a1 + 2 * a2 + 2 * a3 + a4) / 6
            v += dt * (b1 + 2 * b2 + 2 * b3 + b4) / 6
        self.x, self.v = x, v
        return True
