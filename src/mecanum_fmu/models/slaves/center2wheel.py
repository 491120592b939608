"""Center2Wheel FMU: inverse kinematics, chassis twist -> four wheel speeds."""

from pythonfmu import Fmi2Causality, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.slaves.feedthrough import FeedthroughSlave  # inline
from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY, check_geometry, check_wheel_limit, center_to_wheel, limit_wheel_speeds  # inline

_TWIST = ("vx", "vy", "w")
_WHEELS = ("w1", "w2", "w3", "w4")
_GEOMETRY = ("alpha", "L", "W", "R")


class Center2Wheel(FeedthroughSlave):
    author = "mecanum_fmu"
    description = ("Inverse kinematics of a four-wheel O-layout mecanum chassis: body twist "
                   "(vx right, vy forward, w counter-clockwise) -> wheel speeds w1..w4 "
                   "(1 front-right, 2 front-left, 3 rear-left, 4 rear-right). Direct feedthrough. "
                   "w_max > 0 limits the wheel speeds: all four scale down together.")
    UNITS = {"vx": "m/s", "vy": "m/s", "w": "rad/s", "w1": "rad/s", "w2": "rad/s",
             "w3": "rad/s", "w4": "rad/s", "alpha": "rad", "L": "m", "W": "m", "R": "m",
             "w_max": "rad/s"}
    DEPENDENCIES = {name: _TWIST for name in _WHEELS}
    INITIAL_DEPENDENCIES = {name: _TWIST + _GEOMETRY + ("w_max",) for name in _WHEELS}
    # FMI 3.0 only (slaves/fmi3.py): the four wheel speeds also as one array output
    ARRAYS = {"wheel_speeds": (_WHEELS, "w1..w4 as one array (front-right, front-left, rear-left, rear-right)")}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vx = self.vy = self.w = 0.0
        for name, value in DEFAULT_GEOMETRY.items():
            setattr(self, name, value)
        self.w1 = self.w2 = self.w3 = self.w4 = 0.0
        docs = {"vx": "chassis velocity along body +X (right)",
                "vy": "chassis velocity along body +Y (forward)",
                "w": "chassis yaw rate, counter-clockwise positive"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        geometry_docs = {"alpha": "roller axis to wheel axle angle, 0 < alpha < pi/2",
                         "L": "half the distance between left and right wheel centres",
                         "W": "half the distance between front and rear wheel centres",
                         "R": "wheel radius"}
        for name in _GEOMETRY:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=geometry_docs[name]))
        wheel_docs = ("front-right", "front-left", "rear-left", "rear-right")
        for name, where in zip(_WHEELS, wheel_docs):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=f"{where} wheel speed, positive rolls the car forward"))
        # Added last: the value references of the variables above stay as they were.
        self.w_max = 0.0
        self.register_variable(Real("w_max", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed,
                                    description="wheel speed limit (0: none); over it all four "
                                                "wheels scale down together, direction kept"))

    def _update(self):
        # Outputs follow the inputs at once (direct feedthrough), so a master that sets the
        # inputs reads consistent outputs without a step.
        try:
            self.w1, self.w2, self.w3, self.w4 = limit_wheel_speeds(center_to_wheel(
                self.vx, self.vy, self.w, self.alpha, self.L, self.W, self.R), self.w_max)
        except (ArithmeticError, TypeError):
            pass  # invalid geometry: reported by enter_initialization_mode

    def _check(self):
        check_geometry(self.alpha, self.L, self.W, self.R)
        check_wheel_limit(self.w_max)
