"""Test FMU (third-party style): two integrators in a row, v' = u, x' = v (with `order` 3,
three: a' = u, v' = a, x' = v), exact for u held over a step; its output x does not depend
on the current u (the test declares that in the model description, as a C exporter would).
Its response to a held input is of second order (third)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class XtestDouble(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "x'' = u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u, self.a, self.v, self.x, self.order = 0.0, 0.0, 0.0, 0.0, 2
        self.register_variable(Integer("order", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("x", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))
        for name in ("v", "a"):
            self.register_variable(Real(name, causality=Fmi2Causality.local,
                                        variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        h, jerk = step_size, self.order == 3
        acc = self.a if jerk else self.u       # x'' over the step: a + u s (three), u (two)
        self.x += self.v * h + 0.5 * acc * h * h + (self.u * h ** 3 / 6 if jerk else 0.0)
        self.v += acc * h + (0.5 * self.u * h * h if jerk else 0.0)
        if jerk:
            self.a += self.u * h
        return True
