"""Test FMU (third-party style): a sampler, s = sin(t_j) at every t_j = j period, held
between samples (a discrete output, as a sensor's)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class StestSampler(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "s = sin(t_j), held over [t_j, t_j+1)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.period, self.s = 0.1, 0.0
        self.register_variable(Real("period", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("s", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.discrete))

    def do_step(self, current_time, step_size):
        j = math.floor((current_time + step_size) / self.period + 1e-9)
        self.s = math.sin(j * self.period)
        return True
