"""Test FMU (third-party style): tests/fmu_sources/with_state/xtest_spring.py's mass on a
spring with a third output, its acceleration a = (u - k x - c v) / m, which u reaches
directly (the test declares x and v free of u and a dependent on it). a is worked out
whenever it is read; with lazy = 1, only in doStep (and at the end of initialisation), as a
pythonfmu FMU that assigns its outputs in do_step does."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

SUBSTEPS = 16


class XtestAccel(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "m x'' + c x' + k x = u, a = x''"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.m, self.k, self.c, self.u, self.x, self.v = 1.0, 4.0, 0.4, 0.0, 0.0, 0.0
        for name in ("m", "k", "c"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        for name in ("x", "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))
        self.lazy, self._a = 0.0, 0.0
        self.register_variable(Real("lazy", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("a", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=self._read, setter=self._keep))

    def _read(self):
        return self._a if self.lazy else (self.u - self.k * self.x - self.c * self.v) / self.m

    def _keep(self, value):
        self._a = value

    def exit_initialization_mode(self):
        self._a = (self.u - self.k * self.x - self.c * self.v) / self.m

    def _rate(self, x, v):
        return v, (self.u - self.k * x - self.c * v) / self.m

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
        self._a = (self.u - self.k * self.x - self.c * self.v) / self.m
        return True
