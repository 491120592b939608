"""Encoder FMU: one wheel's quadrature encoder, wheel speed in, counts and sampled speed out."""
from pythonfmu import Fmi2Causality, Fmi2Variability, Integer
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.blocks.sensors import ENCODER_SALT, encoder_problem, ticks_of, wrap_int32  # inline
from mecanum_fmu.models.slaves.sampled import SampledSensor  # inline


class Encoder(SampledSensor):
    author = "mecanum_fmu"
    description = ("Wheel encoder: integrates the wheel speed w into the wheel angle (a state); "
                   "ticks = floor(angle cpr / 2 pi), a 32-bit counter; every period it outputs "
                   "w_meas = the tick difference over the period / period (the mean speed over "
                   "the period ending at the sample), plus white noise of sd sigma "
                   "(reproducible: indexed by sample), held between samples.")
    SALT = ENCODER_SALT
    UNITS = {"w": "rad/s", "w_meas": "rad/s", "period": "s", "sigma": "rad/s"}
    DEPENDENCIES = {"w_meas": (), "ticks": ()}
    INITIAL_DEPENDENCIES = {"w_meas": (), "ticks": ()}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.cpr, self.ticks = 4096, 0
        self.register_sensor("wheel speed, positive rolls the car forward",
                             "measured wheel speed: tick difference over the last sample "
                             "period, plus noise; held between samples")
        self.register_variable(Integer("cpr", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed,
                                       description="counts per wheel revolution (quadrature "
                                                   "edges, at the wheel); 0: an ideal encoder, "
                                                   "no quantisation"))
        self.register_variable(Integer("ticks", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       description="the count now, floor(angle cpr / 2 pi), "
                                                   "wrapping as a signed 32-bit counter; 0 "
                                                   "with cpr = 0"))

    def _problem(self):
        return encoder_problem(self.cpr, self.period, self.sigma)

    def _count_of(self, integral):
        return ticks_of(integral, self.cpr) if self.cpr else integral

    def _publish(self):
        self.ticks = wrap_int32(ticks_of(self._integral, self.cpr)) if self.cpr else 0
