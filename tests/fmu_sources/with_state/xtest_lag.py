"""Test FMU (third-party style): a first-order lag x' = -k x + u, exact for u held over a
step (x <- x e^(-k h) + u (1 - e^(-k h)) / k); its output x does not depend on the current
u (the test declares that in the model description, as a C exporter would). With `lim`, its
input saturates at +-lim (x' = -k x + sat(u)): where it is saturated, x does not move with
it, and a probe there measures no response at all. With `min_step`, it refuses (Discard) a
step shorter than that."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestLag(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.lim, self.min_step, self.u, self.x = 1.0, 1e300, 0.0, 0.0, 0.0
        for name in ("k", "lim", "min_step"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        if step_size < self.min_step:
            return False
        decay = math.exp(-self.k * step_size)
        u = max(-self.lim, min(self.lim, self.u))
        self.x = self.x * decay + u * (1.0 - decay) / self.k
        return True
