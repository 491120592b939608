"""Test FMU (third-party style): a first-order lag x' = -k x + u, exact for u held over a
step, with two outputs: x, and y = x + u, which u reaches directly (the test declares x free
of u and y dependent on it, as a C exporter would)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestThrough(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + u, y = x + u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.u, self.x = 1.0, 0.0, 0.0
        self.register_variable(Real("k", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: self.x + self.u))

    def do_step(self, current_time, step_size):
        decay = math.exp(-self.k * step_size)
        self.x = self.x * decay + self.u * (1.0 - decay) / self.k
        return True
