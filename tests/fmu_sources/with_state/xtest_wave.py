"""Test FMU (third-party style): a source, u = cos(omega t) at the FMU's current time."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestWave(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "u = cos(omega t)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.omega, self.time = 1.0, 0.0
        self.register_variable(Real("omega", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: math.cos(self.omega * self.time)))
        self.register_variable(Real("time", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous))

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.time = start_time

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
