"""Test FMU (third-party style, no declared dependencies): counts its own steps.

Outputs: counter (Integer) = number of steps taken, flag (Boolean) = counter is even.
"""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer


class MtestCounter(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "Counts its steps: counter = steps taken, flag = counter is even"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.counter = 0
        self.flag = True
        self.register_variable(Integer("counter", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete))
        self.register_variable(Boolean("flag", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete))

    def do_step(self, current_time, step_size):
        self.counter += 1
        self.flag = self.counter % 2 == 0
        return True
