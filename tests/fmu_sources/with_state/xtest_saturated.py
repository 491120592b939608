"""Test FMU (third-party style): a first-order lag whose input saturates, x' = -k x +
sat(u), sat(u) = u clipped to [-lim, lim], exact for u held over a step; its output x does
not depend on the current u (declared in the model description, as a C exporter would).
Where the input is saturated, the output does not move with it: a probe there measures no
response at all."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestSaturated(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + sat(u)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.lim, self.u, self.x = 2.0, 0.5, 0.0, 0.0
        for name in ("k", "lim"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        u = max(-self.lim, min(self.lim, self.u))
        z = math.exp(-self.k * step_size)
        self.x = self.x * z + u * (1 - z) / self.k
        return True
