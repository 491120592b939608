"""Test FMU (third-party style): three lags in a row, x1' = -a x1 + u, x2' = -b x2 + x1,
x3' = -c x3 + x2, integrated over each step by RK4 substeps (16, or as many as keep each
lag's rate times the substep under 0.25) for the u held over it; its
outputs x1, x2, x3 do not depend on the current u (the test declares that in the model
description, as a C exporter would). A response of third order: with one lag much faster
than the step (a or c 300 at 0.01 s .. 0.1 s), a part gone within the step, or a pole of
0.05 per step that two poles' fit takes into an oscillating pair."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

SUBSTEPS = 16


class XtestTriple(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "three lags in a row"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.a, self.b, self.c = 1.0, 2.0, 3.0
        self.u, self.x1, self.x2, self.x3 = 0.0, 0.0, 0.0, 0.0
        for name in ("a", "b", "c"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        for name in ("x1", "x2", "x3"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))

    def _rate(self, s):
        x1, x2, x3 = s
        return -self.a * x1 + self.u, -self.b * x2 + x1, -self.c * x3 + x2

    def do_step(self, current_time, step_size):
        n = max(SUBSTEPS, math.ceil(4 * max(self.a, self.b, self.c) * step_size))
        dt = step_size / n
        s = (self.x1, self.x2, self.x3)
        for _ in range(n):
            k1 = self._rate(s)
            k2 = self._rate([x + 0.5 * dt * k for x, k in zip(s, k1)])
            k3 = self._rate([x + 0.5 * dt * k for x, k in zip(s, k2)])
            k4 = self._rate([x + dt * k for x, k in zip(s, k3)])
            s = [x + dt * (p + 2 * q + 2 * r + w) / 6 for x, p, q, r, w in zip(s, k1, k2, k3,
                                                                                 k4)]
        self.x1, self.x2, self.x3 = s
        return True
