"""Gyro FMU: the yaw rate in, a sampled yaw rate with bias and white noise out."""
from pythonfmu import Fmi2Causality, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.blocks.sensors import GYRO_SALT, gyro_problem  # inline
from mecanum_fmu.models.slaves.sampled import SampledSensor  # inline


class Gyro(SampledSensor):
    author = "mecanum_fmu"
    description = ("Yaw-rate gyro: every period it outputs w_meas = the mean yaw rate over the "
                   "period ending at the sample + bias + white noise of sd sigma "
                   "(reproducible: indexed by sample), held between samples.")
    SALT = GYRO_SALT
    UNITS = {"w": "rad/s", "w_meas": "rad/s", "period": "s", "sigma": "rad/s", "bias": "rad/s"}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.register_sensor("true yaw rate, counter-clockwise positive",
                             "measured yaw rate: the mean over the last sample period + bias "
                             "+ noise; held between samples")
        self.register_variable(Real("bias", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed,
                                    description="constant offset added to every sample"))

    def _problem(self):
        return gyro_problem(self.period, self.sigma, self.bias)
