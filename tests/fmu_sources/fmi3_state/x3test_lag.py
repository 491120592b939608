"""Test FMU (third-party style, FMI 3.0): a first-order lag x' = -k x + u, exact for u held
over a step; its output x does not depend on the current u (declared by the test)."""
import math

from pythonfmu3 import Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64


class X3testLag(Fmi3Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.u, self.x, self.time = 1.0, 0.0, 0.0, 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("k", causality=Fmi3Causality.parameter,
                                       variability=Fmi3Variability.fixed))
        self.register_variable(Float64("u", causality=Fmi3Causality.input,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("x", causality=Fmi3Causality.output,
                                       variability=Fmi3Variability.continuous))

    def do_step(self, current_time, step_size):
        decay = math.exp(-self.k * step_size)
        self.x = self.x * decay + self.u * (1.0 - decay) / self.k
        self.time = current_time + step_size
        return True
