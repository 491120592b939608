"""Test FMU that fails on purpose.

y = the time reached. Once current_time >= fail_at, do_step fails: it returns False when
mode = 0 and raises when mode = 1. With fail_init = true, initialization fails instead.
"""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class MtestFailing(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "Fails its step at fail_at (mode 0: returns False, 1: raises) or at init"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.fail_at = 5.0
        self.mode = 0
        self.fail_init = False
        self.y = 0.0
        self.register_variable(Real("fail_at", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed))
        self.register_variable(Integer("mode", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(Boolean("fail_init", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def exit_initialization_mode(self):
        if self.fail_init:
            raise RuntimeError("mtest_failing refuses to initialize")

    def do_step(self, current_time, step_size):
        if current_time >= self.fail_at:
            if self.mode == 1:
                raise RuntimeError(f"mtest_failing breaks at t = {current_time}")
            return False
        self.y = current_time + step_size
        return True
