"""Test FMU (third-party style): a source, u = cos(omega t) at the FMU's current time; with a
`period`, its output moves on a grid of its own, as a fixed-step solver's or a sampled
controller's: u = cos(omega t_p), t_p the last multiple of the period at or before t."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestWave(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "u = cos(omega t)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.omega, self.period, self.time = 1.0, 0.0, 0.0
        for name in ("omega", "period"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: math.cos(self.omega * self._grid())))
        self.register_variable(Real("time", causality=Fmi2Causality.local,
                                    variability=Fmi2Variability.continuous))

    def _grid(self):
        if self.period <= 0.0:
            return self.time
        return self.period * math.floor(self.time / self.period + 1e-9)

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.time = start_time

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
