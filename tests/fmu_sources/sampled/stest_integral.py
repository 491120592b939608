"""Test FMU (third-party style): x' = u, exact for u held over a step (x += u h); its output
does not depend on the current u (the test declares that in the model description)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class StestIntegral(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u, self.x = 0.0, 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        self.x += self.u * step_size
        return True
