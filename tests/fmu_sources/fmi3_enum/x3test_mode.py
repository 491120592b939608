"""Test FMU (third-party style, FMI 3.0): an Enumeration input `mode_in` (Mode: slow = 1,
fast = 2) and output `mode` (the input, as FMI 3.0's Feedthrough has it), beside a Float64
output y = the mode as a number and an Int32 output `count` (its steps). FMI 3.0 gets and
sets an Enumeration as Int64, which the master's Integer kind holds. pythonfmu3 0.3.4's
Enumeration cannot be built (it has no dimensions): the two are Int64 here, and the test
(helpers.mode_fmu3) rewrites them into Enumerations of a declared type."""
from pythonfmu3 import Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64, Int32, Int64


class X3testMode(Fmi3Slave):
    author = "mecanum_fmu tests"
    description = "mode = mode_in, y = mode, count = steps"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.mode_in, self.mode, self.y, self.count, self.time = 1, 1, 1.0, 0, 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Int64("mode_in", causality=Fmi3Causality.input,
                                     variability=Fmi3Variability.discrete))
        self.register_variable(Int64("mode", causality=Fmi3Causality.output,
                                     variability=Fmi3Variability.discrete))
        self.register_variable(Float64("y", causality=Fmi3Causality.output,
                                       variability=Fmi3Variability.discrete))
        self.register_variable(Int32("count", causality=Fmi3Causality.output,
                                     variability=Fmi3Variability.discrete))

    def do_step(self, current_time, step_size):
        self.mode = self.mode_in
        self.y = float(self.mode)
        self.count += 1
        self.time = current_time + step_size
        return True
