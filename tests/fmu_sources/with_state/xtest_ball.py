"""Test FMU (third-party style): a bouncing ball, h'' = -g, its speed turned back and cut by
`e` at h = 0, each bounce found inside doStep (as the Reference FMUs' BouncingBall finds its
events), at rest once a bounce leaves it under 1e-3 m/s. Its height has a kink at each bounce
that no breakpoint announces. Every value it holds is registered, so that its state is
saved and set whole (pythonfmu saves the registered variables alone)."""
import math

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestBall(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "a bouncing ball"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.g, self.e, self.h, self.v, self.rest = 9.81, 0.7, 1.0, 0.0, False
        for name in ("g", "e"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        for name in ("h", "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))
        self.register_variable(Boolean("rest", causality=Fmi2Causality.local,
                                       variability=Fmi2Variability.discrete))

    def do_step(self, current_time, step_size):
        left, h, v = step_size, self.h, self.v
        while left > 0 and not self.rest:
            hit = (v + math.sqrt(max(v * v + 2 * self.g * h, 0.0))) / self.g
            if hit > left:
                h, v, left = h + v * left - 0.5 * self.g * left * left, v - self.g * left, 0.0
            else:
                h, v, left = 0.0, -self.e * (v - self.g * hit), left - hit
                self.rest = abs(v) < 1e-3
                v = 0.0 if self.rest else v
        self.h, self.v = max(h, 0.0), v
        return True
