"""Test FMU (third-party style), without a state by default: a proportional controller, u =
kp e + cube e^3 + i, e = r - y (linear where cube = 0, the default), its output computed
from its inputs whenever it is read (direct feedthrough); with lazy = 1, only in its doStep,
as some exporters do against FMI 2.0 (an input set after the step does not move it). With ki
> 0, an integral part i (a state, saved with the FMU's) that sums ki e h over the steps that
start at or after t = after, and none before. With quantum > 0, y is read quantized, as a
sensor with that resolution gives it: quantum round(y / quantum)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestGain(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "u = kp e + cube e^3 + i, e = r - y"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.kp, self.cube, self.lazy, self.r, self.y = 1.0, 0.0, 0.0, 0.0, 0.0
        self.ki, self.after, self.i, self.quantum = 0.0, 0.0, 0.0, 0.0
        self._stepped = 0.0
        for name in ("kp", "cube", "lazy", "ki", "after", "quantum"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("r", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("y", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("i", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("u", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=self._u))

    def _law(self):
        y = self.quantum * math.floor(self.y / self.quantum + 0.5) if self.quantum else self.y
        e = self.r - y
        return self.kp * e + self.cube * e ** 3 + self.i

    def _u(self):
        return self._stepped if self.lazy else self._law()

    def do_step(self, current_time, step_size):
        if self.ki and current_time >= self.after - 1e-9:
            self.i += self.ki * (self.r - self.y) * step_size
        self._stepped = self._law()
        return True
