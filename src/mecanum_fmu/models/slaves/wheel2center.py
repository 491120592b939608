"""Wheel2Center FMU: forward kinematics, four wheel speeds -> chassis twist."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.slaves.feedthrough import FeedthroughSlave  # inline
from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY, check_geometry, check_radius_deviations, instantaneous_center, wheel_to_center  # inline

_WHEELS = ("w1", "w2", "w3", "w4")
_TWIST = ("vx", "vy", "w")
_GEOMETRY = ("alpha", "L", "W", "R")
_ICR = ("icr_x", "icr_y", "has_icr")
_DEVIATIONS = ("dR1", "dR2", "dR3", "dR4")


class Wheel2Center(FeedthroughSlave):
    author = "mecanum_fmu"
    description = ("Forward kinematics of a four-wheel O-layout mecanum chassis: wheel speeds "
                   "w1..w4 -> least-squares body twist (vx right, vy forward, w counter-clockwise). "
                   "Direct feedthrough.")
    UNITS = {"vx": "m/s", "vy": "m/s", "w": "rad/s", "w1": "rad/s", "w2": "rad/s",
             "w3": "rad/s", "w4": "rad/s", "alpha": "rad", "L": "m", "W": "m", "R": "m",
             "icr_x": "m", "icr_y": "m",
             "dR1": "m", "dR2": "m", "dR3": "m", "dR4": "m"}
    DEPENDENCIES = {name: _WHEELS for name in _TWIST + _ICR}
    INITIAL_DEPENDENCIES = {name: _WHEELS + _GEOMETRY + _DEVIATIONS for name in _TWIST + _ICR}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.w1 = self.w2 = self.w3 = self.w4 = 0.0
        for name, value in DEFAULT_GEOMETRY.items():
            setattr(self, name, value)
        self.dR1 = self.dR2 = self.dR3 = self.dR4 = 0.0
        self.vx = self.vy = self.w = 0.0
        self.icr_x = self.icr_y = 0.0
        self.has_icr = False
        wheel_docs = ("front-right", "front-left", "rear-left", "rear-right")
        for name, where in zip(_WHEELS, wheel_docs):
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=f"{where} wheel speed, positive rolls the car forward"))
        geometry_docs = {"alpha": "roller axis to wheel axle angle, 0 < alpha < pi/2",
                         "L": "half the distance between left and right wheel centres",
                         "W": "half the distance between front and rear wheel centres",
                         "R": "wheel radius"}
        for name in _GEOMETRY:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=geometry_docs[name]))
        docs = {"vx": "chassis velocity along body +X (right), least squares",
                "vy": "chassis velocity along body +Y (forward), least squares",
                "w": "chassis yaw rate, counter-clockwise positive, least squares"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        # Registered after the twist so the earlier value references stay unchanged.
        icr_docs = {"icr_x": "instantaneous centre of rotation, body X (-vy/w); 0 without one",
                    "icr_y": "instantaneous centre of rotation, body Y (vx/w); 0 without one"}
        for name in ("icr_x", "icr_y"):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=icr_docs[name]))
        self.register_variable(Boolean("has_icr", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       description="true when |w| >= 1e-9 rad/s (not a pure "
                                                   "translation), so the ICR exists"))
        # Registered last so every earlier value reference stays unchanged.
        for name, where in zip(_DEVIATIONS, wheel_docs):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=f"{where} wheel effective-radius deviation: "
                                                    "the forward kinematics uses R + this "
                                                    "(worn or slipping wheel); 0 is nominal"))

    def _update(self):
        # Direct feedthrough: outputs follow the inputs at once, no step needed.
        try:
            self.vx, self.vy, self.w = wheel_to_center(
                self.w1, self.w2, self.w3, self.w4, self.alpha, self.L, self.W, self.R,
                (self.dR1, self.dR2, self.dR3, self.dR4))
            self.icr_x, self.icr_y, self.has_icr = instantaneous_center(self.vx, self.vy, self.w)
        except (ArithmeticError, TypeError):
            pass  # invalid geometry: reported by enter_initialization_mode

    def _check(self):
        check_geometry(self.alpha, self.L, self.W, self.R)
        check_radius_deviations(self.R, (self.dR1, self.dR2, self.dR3, self.dR4))
