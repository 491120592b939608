"""PoseIntegrator FMU: body-frame twist -> world-frame pose, exact for held inputs."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.pose import pose_step  # inline

_TWIST = ("vx", "vy", "w")
_POSE = ("x", "y", "theta")
_START = ("x0", "y0", "theta0")


class PoseIntegrator(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Integrates a body-frame chassis twist (vx right, vy forward, w) into the "
                   "world-frame pose (x, y, theta). Exact (SE(2) exponential) for inputs held "
                   "over a step; outputs do not depend on the current inputs.")
    UNITS = {"vx": "m/s", "vy": "m/s", "w": "rad/s", "x": "m", "y": "m", "theta": "rad",
             "x0": "m", "y0": "m", "theta0": "rad"}
    DEPENDENCIES = {name: () for name in _POSE}
    INITIAL_DEPENDENCIES = dict(zip(_POSE, ((s,) for s in _START)))
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.vx = self.vy = self.w = 0.0
        self.x0 = self.y0 = self.theta0 = 0.0
        self.x = self.y = self.theta = 0.0
        docs = {"vx": "body-frame velocity along +X (right)",
                "vy": "body-frame velocity along +Y (forward)",
                "w": "yaw rate, counter-clockwise positive"}
        for name in _TWIST:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        start_docs = {"x0": "initial world x", "y0": "initial world y",
                      "theta0": "initial heading (0: body +Y along world +Y)"}
        for name in _START:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed,
                                        description=start_docs[name]))
        pose_docs = {"x": "world-frame position x", "y": "world-frame position y",
                     "theta": "heading, counter-clockwise from the start frame"}
        for name in _POSE:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=pose_docs[name]))

    def enter_initialization_mode(self):
        self.x, self.y, self.theta = self.x0, self.y0, self.theta0

    def exit_initialization_mode(self):
        self.x, self.y, self.theta = self.x0, self.y0, self.theta0

    def do_step(self, current_time, step_size):
        self.x, self.y, self.theta = pose_step(
            self.x, self.y, self.theta, self.vx, self.vy, self.w, step_size)
        return True
