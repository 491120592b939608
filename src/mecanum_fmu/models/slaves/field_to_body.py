"""FieldToBody FMU: a world-frame ("field-oriented") command -> the body twist at the heading."""
from pythonfmu import Fmi2Causality, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.slaves.feedthrough import FeedthroughSlave  # inline
from mecanum_fmu.models.blocks.pose import world_to_body  # inline

_INPUTS = ("vX", "vY", "omega", "theta")
_TWIST = ("vx", "vy", "w")


class FieldToBody(FeedthroughSlave):
    author = "mecanum_fmu"
    description = ("Field-oriented command: world-frame velocity (vX, vY) and yaw rate omega, "
                   "rotated by the heading theta into the body twist (vx right, vy forward, w "
                   "counter-clockwise) for either holonomic chassis. The identity at theta = 0. "
                   "Direct feedthrough; theta may come back from PoseIntegrator (no loop).")
    UNITS = {"vX": "m/s", "vY": "m/s", "omega": "rad/s", "theta": "rad",
             "vx": "m/s", "vy": "m/s", "w": "rad/s"}
    DEPENDENCIES = {"vx": ("vX", "vY", "theta"), "vy": ("vX", "vY", "theta"), "w": ("omega",)}
    INITIAL_DEPENDENCIES = DEPENDENCIES
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vX = self.vY = self.omega = self.theta = 0.0
        self.vx = self.vy = self.w = 0.0
        docs = {"vX": "commanded velocity along world +X (right at heading 0)",
                "vY": "commanded velocity along world +Y (forward at heading 0)",
                "omega": "commanded yaw rate, counter-clockwise positive",
                "theta": "chassis heading, counter-clockwise from world +Y to body +Y"}
        for name in _INPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        out_docs = {"vx": "chassis velocity along body +X (right)",
                    "vy": "chassis velocity along body +Y (forward)",
                    "w": "chassis yaw rate, counter-clockwise positive (= omega)"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=out_docs[name]))

    def _update(self):
        self.vx, self.vy = world_to_body(self.vX, self.vY, self.theta)
        self.w = self.omega
