"""Test FMU (third-party style): a first-order lag x' = -k x + u, exact for u held over a
step, with two outputs: x, and y = x + u, which u reaches directly (the test declares x free
of u and y dependent on it, as a C exporter would). y is worked out whenever it is read; with
lazy = 1, only in doStep (and at the end of initialisation), as a pythonfmu FMU that assigns
its outputs in do_step does: an input set after the step does not move it."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestThrough(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + u, y = x + u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.lazy, self.u, self.x, self._y = 1.0, 0.0, 0.0, 0.0, 0.0
        for name in ("k", "lazy"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=self._read, setter=self._keep))

    def _read(self):
        return self._y if self.lazy else self.x + self.u

    def _keep(self, value):         # a saved state set back: the lazy value it held
        self._y = value

    def exit_initialization_mode(self):
        self._y = self.x + self.u

    def do_step(self, current_time, step_size):
        decay = math.exp(-self.k * step_size)
        self.x = self.x * decay + self.u * (1.0 - decay) / self.k
        self._y = self.x + self.u
        return True
