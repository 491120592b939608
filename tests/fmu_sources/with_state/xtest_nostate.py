"""Test FMU (third-party style): the lag x' = -k x + u that declares canGetAndSetFMUstate
(the test builds it so) and fails to save its state: its fmi2GetFMUstate raises, which
pythonfmu returns as Fatal."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestNostate(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x' = -k x + u, and no state to save"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k, self.u, self.x = 1.0, 0.0, 0.0
        self.register_variable(Real("k", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def _get_fmu_state(self):
        raise RuntimeError("no state today")

    def do_step(self, current_time, step_size):
        decay = math.exp(-self.k * step_size)
        self.x = self.x * decay + self.u * (1.0 - decay) / self.k
        return True
