"""Test FMU (third-party style): y = s + t, a continuous output that follows its input at
once (direct feedthrough) and the time."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class StestRamp(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "y = s + t"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.s, self.time = 0.0, 0.0
        self.register_variable(Real("s", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: self.s + self.time))
        self.register_variable(Real("time", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous))

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.time = start_time

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
