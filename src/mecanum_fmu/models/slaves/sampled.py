"""What the sampled sensors share (Encoder, Gyro); inlined into each FMU script like the block
maths (the line that imports it ends in `# inline`)."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.sensors import check_sensor, measured_speed, samples_until, sample_time, standard_normal  # inline

# Not model variables, but the sensor's state: fmi2GetFMUstate carries them (a rollback
# repeats the same samples and the same noise).
_STATE = ("_t0", "_integral", "_count", "_next_k")


class SampledSensor(QuickState, Fmi2Slave):
    """A sensor that integrates its input `w` as a state and, at each sample time t0 + k*period,
    outputs the mean of `w` over the period ending there (from two counts of the integral),
    plus `bias`, plus `sigma` times the k-th normal draw of the stream (seed, SALT); the output
    is held between samples. Outputs do not depend on the current input."""
    SALT = 0
    DEPENDENCIES = {"w_meas": ()}
    INITIAL_DEPENDENCIES = {"w_meas": ()}

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.w = self.w_meas = 0.0
        self.period, self.sigma, self.seed, self.bias, self.cpr = 0.01, 0.0, 0, 0.0, 0
        self._t0, self._integral, self._count, self._next_k = 0.0, 0.0, 0, 1

    def register_sensor(self, input_doc: str, output_doc: str):
        self.register_variable(Real("w", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description=input_doc))
        self.register_variable(Real("w_meas", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.discrete,
                                    description=output_doc))
        docs = {"period": "sample period: a sample at every start_time + k*period, held between "
                          "samples (make it a multiple of the master's step)",
                "sigma": "white noise on each sample: its standard deviation (0: none)"}
        for name in ("period", "sigma"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=docs[name]))
        self.register_variable(Integer("seed", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed,
                                       description="noise seed: sample k's noise is a function "
                                                   "of (seed, k) only"))

    def _problem(self):
        raise NotImplementedError

    def _count_of(self, integral: float):
        return integral           # the Gyro counts the integral itself (no quantisation)

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t0 = float(start_time)

    def enter_initialization_mode(self):
        try:
            check_sensor(self._problem())
        except ValueError as err:
            self.log(f"{type(self).__name__}: {err}", Fmi2Status.error)
            raise
        self._integral, self._count, self._next_k = 0.0, self._count_of(0.0), 1
        self.w_meas = 0.0
        self._publish()

    def exit_initialization_mode(self):
        self.enter_initialization_mode()   # parameters may have changed during initialization

    def _publish(self):
        """Set any output that follows the integral between samples (the Encoder's ticks)."""

    def do_step(self, current_time, step_size):
        for k in samples_until(self._t0, self.period, self._next_k, current_time + step_size):
            # the input is held over the step, so the integral is linear inside it
            at = self._integral + self.w * (sample_time(self._t0, self.period, k) - current_time)
            count = self._count_of(at)
            self.w_meas = (measured_speed(count, self._count, self.cpr, self.period) + self.bias
                           + self.sigma * standard_normal(self.seed, self.SALT, k))
            self._count, self._next_k = count, k + 1
        self._integral += self.w * step_size
        self._publish()
        return True

    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state.update({name: getattr(self, name) for name in _STATE})
        return state
