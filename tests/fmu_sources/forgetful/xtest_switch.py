"""Test FMU (a pythonfmu FMU whose saved state misses what it holds): u = 1 until the switch
opens at t = `at`, then 0, the opening kept in an attribute it does not register. pythonfmu
saves and sets the registered variables alone, so its state set back to t0 after it opened
stays open (tests/test_estimate_any_fmu.py)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class XtestSwitch(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "u = 1 until the switch opens"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.at, self.opened = 1.0, False
        self.register_variable(Real("at", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: 0.0 if self.opened else 1.0))

    def do_step(self, current_time, step_size):
        self.opened = self.opened or current_time + step_size >= self.at - 1e-9
        return True
