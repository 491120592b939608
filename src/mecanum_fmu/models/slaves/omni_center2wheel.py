"""OmniCenter2Wheel FMU: inverse kinematics of the 45-degree omni X-drive, twist -> wheel speeds."""
from pythonfmu import Fmi2Causality, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.slaves.feedthrough import FeedthroughSlave  # inline
from mecanum_fmu.models.blocks.omni import check_omni_geometry, omni_center_to_wheel  # inline

_TWIST = ("vx", "vy", "w")
_WHEELS = ("w1", "w2", "w3", "w4")
_GEOMETRY = ("L", "R")
WHEEL_DOCS = ("front-left", "rear-left", "rear-right", "front-right")


class OmniCenter2Wheel(FeedthroughSlave):
    author = "mecanum_fmu"
    description = ("Inverse kinematics of a four-wheel 45-degree omni X-drive: body twist "
                   "(vx right, vy forward, w counter-clockwise) -> wheel speeds w1..w4 = rim "
                   "speed / R (1 front-left, 2 rear-left, 3 rear-right, 4 front-right; positive "
                   "pushes the chassis counter-clockwise). Direct feedthrough.")
    UNITS = {"vx": "m/s", "vy": "m/s", "w": "rad/s", "w1": "rad/s", "w2": "rad/s",
             "w3": "rad/s", "w4": "rad/s", "L": "m", "R": "m"}
    DEPENDENCIES = {name: _TWIST for name in _WHEELS}
    INITIAL_DEPENDENCIES = {name: _TWIST + _GEOMETRY for name in _WHEELS}
    # FMI 3.0 only (slaves/fmi3.py): the four wheel speeds also as one array output
    ARRAYS = {"wheel_speeds": (_WHEELS, "w1..w4 as one array (front-left, rear-left, rear-right, front-right)")}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vx = self.vy = self.w = 0.0
        self.L, self.R = 0.2, 0.05
        self.w1 = self.w2 = self.w3 = self.w4 = 0.0
        docs = {"vx": "chassis velocity along body +X (right)",
                "vy": "chassis velocity along body +Y (forward)",
                "w": "chassis yaw rate, counter-clockwise positive"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        geometry_docs = {"L": "distance from the chassis centre to each wheel centre",
                         "R": "wheel radius"}
        for name in _GEOMETRY:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=geometry_docs[name]))
        for name, where in zip(_WHEELS, WHEEL_DOCS):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=f"{where} wheel speed, positive pushes "
                                                    "the chassis counter-clockwise"))

    def _update(self):
        # Direct feedthrough: outputs follow the inputs at once, no step needed.
        try:
            self.w1, self.w2, self.w3, self.w4 = omni_center_to_wheel(
                self.vx, self.vy, self.w, self.L, self.R)
        except (ArithmeticError, TypeError):
            pass  # invalid geometry: reported by enter_initialization_mode

    def _check(self):
        check_omni_geometry(self.L, self.R)
