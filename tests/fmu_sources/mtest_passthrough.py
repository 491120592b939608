"""Test FMU (third-party style, no declared dependencies): copies inputs to outputs.

n_out, b_out and u_out return the current n_in, b_in and u_in at once (direct feedthrough,
no step needed); acc integrates u_in held over each step (acc += u_in * step_size).
"""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class MtestPassthrough(Fmi2Slave):
    author = "mecanum_fmu tests"
    description = "Integer/Boolean/Real passthrough plus a held-input integrator"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.n_in = 0
        self.b_in = False
        self.u_in = 0.0
        self.acc = 0.0
        self.register_variable(Integer("n_in", causality=Fmi2Causality.input,
                                       variability=Fmi2Variability.discrete))
        self.register_variable(Boolean("b_in", causality=Fmi2Causality.input,
                                       variability=Fmi2Variability.discrete))
        self.register_variable(Real("u_in", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Integer("n_out", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       getter=lambda: self.n_in))
        self.register_variable(Boolean("b_out", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       getter=lambda: self.b_in))
        self.register_variable(Real("u_out", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    getter=lambda: self.u_in))
        self.register_variable(Real("acc", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        self.acc += self.u_in * step_size
        return True
