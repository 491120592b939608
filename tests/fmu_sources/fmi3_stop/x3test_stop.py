"""Test FMU (third-party style, FMI 3.0): a lag x' = -x + u that asks to end the simulation
(fmi3DoStep's terminateSimulation) on the step that reaches t_end, as the Reference FMUs'
Stair does at 9 s (there with FMI 2.0's fmi2Discard and fmi2Terminated)."""
import math

from pythonfmu3 import (Fmi3Causality, Fmi3Slave, Fmi3StepResult, Fmi3Variability,
                        Float64)


class X3testStop(Fmi3Slave):
    author = "mecanum_fmu tests"
    description = "x' = -x + u; ends the simulation at t_end"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.t_end, self.u, self.x, self.time = 1.0, 0.0, 0.0, 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("t_end", causality=Fmi3Causality.parameter,
                                       variability=Fmi3Variability.fixed))
        self.register_variable(Float64("u", causality=Fmi3Causality.input,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("x", causality=Fmi3Causality.output,
                                       variability=Fmi3Variability.continuous))

    def do_step(self, current_time, step_size):
        decay = math.exp(-step_size)
        self.x = self.x * decay + self.u * (1.0 - decay)
        self.time = current_time + step_size
        return Fmi3StepResult(terminateSimulation=self.time >= self.t_end - 1e-9 * step_size)
