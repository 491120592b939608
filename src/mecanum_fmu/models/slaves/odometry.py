"""Odometry FMU: measured wheel speeds (and optionally a gyro) in, the believed pose out."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY, check_geometry, wheel_to_center  # inline
from mecanum_fmu.models.blocks.pose import pose_step  # inline
from mecanum_fmu.models.blocks.odometry import check_odometry, euler_step  # inline
from mecanum_fmu.models.blocks.sensors import samples_until  # inline

_WHEELS = ("w1", "w2", "w3", "w4")
_INPUTS = _WHEELS + ("w_gyro",)
_POSE = ("x", "y", "theta")
_START = ("x0", "y0", "theta0")
_GEOMETRY = ("alpha", "L", "W", "R")
_STATE = ("_t0", "_next_k")


class Odometry(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Wheel odometry as ros2_controllers' mecanum_drive_controller computes it: "
                   "at every start_time + k*period, the twist from the measured wheel speeds "
                   "w1..w4 (the seed's forward kinematics; ros2's formulas at 45 deg) moves the "
                   "believed pose over one period: update 'euler' (the heading first, then the "
                   "position with the new heading) or 'exact' (SE(2)); heading 'gyro' takes the "
                   "yaw rate from w_gyro. The pose is held between samples; it uses the inputs "
                   "set for the end of the step (a Gauss-Seidel master).")
    UNITS = {**{n: "rad/s" for n in _INPUTS}, "x": "m", "y": "m", "theta": "rad",
             "x0": "m", "y0": "m", "theta0": "rad", "period": "s",
             "alpha": "rad", "L": "m", "W": "m", "R": "m"}
    DEPENDENCIES = {name: _INPUTS for name in _POSE}
    INITIAL_DEPENDENCIES = {name: (f"{name}0",) for name in _POSE}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.w1 = self.w2 = self.w3 = self.w4 = self.w_gyro = 0.0
        self.x0 = self.y0 = self.theta0 = 0.0
        self.x = self.y = self.theta = 0.0
        for name, value in DEFAULT_GEOMETRY.items():
            setattr(self, name, value)
        self.period, self.update, self.heading = 0.01, "euler", "wheels"
        self._t0, self._next_k = 0.0, 1
        self._register()

    def _register(self):
        docs = dict(zip(_WHEELS, (f"measured {w} wheel speed (an Encoder's w_meas)" for w in
                                  ("front-right", "front-left", "rear-left", "rear-right"))))
        docs["w_gyro"] = "measured yaw rate (a Gyro's w_meas); used with heading = gyro"
        for name in _INPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        pose_docs = {"x": "believed world-frame position x", "y": "believed world-frame "
                     "position y", "theta": "believed heading, counter-clockwise"}
        for name in _POSE:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.discrete,
                                        description=pose_docs[name]))
        params = {"x0": "initial believed x", "y0": "initial believed y",
                  "theta0": "initial believed heading",
                  "alpha": "roller axis to wheel axle angle the odometry assumes",
                  "L": "half the left-right wheel distance the odometry assumes",
                  "W": "half the front-rear wheel distance the odometry assumes",
                  "R": "wheel radius the odometry assumes",
                  "period": "update period: an update at every start_time + k*period (make "
                            "it a multiple of the master's step)"}
        for name, doc in params.items():
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=doc))
        strings = {"update": "euler (ros2_controllers: heading first, then position with the "
                             "new heading) or exact (SE(2) exponential)",
                   "heading": "wheels (yaw rate from the wheel speeds) or gyro (from w_gyro)"}
        for name, doc in strings.items():
            self.register_variable(String(name, causality=Fmi2Causality.parameter,
                                          variability=Fmi2Variability.fixed, description=doc))

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t0 = float(start_time)

    def enter_initialization_mode(self):
        try:
            check_geometry(self.alpha, self.L, self.W, self.R)
            check_odometry(self.period, self.update, self.heading)
        except ValueError as err:
            self.log(f"Odometry: {err}", Fmi2Status.error)
            raise
        self.x, self.y, self.theta = self.x0, self.y0, self.theta0
        self._next_k = 1

    def exit_initialization_mode(self):
        self.enter_initialization_mode()

    def do_step(self, current_time, step_size):
        samples = samples_until(self._t0, self.period, self._next_k, current_time + step_size)
        if samples:
            vx, vy, w = wheel_to_center(self.w1, self.w2, self.w3, self.w4,
                                        self.alpha, self.L, self.W, self.R)
            if self.heading == "gyro":
                w = self.w_gyro
            move = euler_step if self.update == "euler" else pose_step
            for _ in samples:
                self.x, self.y, self.theta = move(self.x, self.y, self.theta,
                                                  vx, vy, w, self.period)
            self._next_k = samples[-1] + 1
        return True

    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state.update({name: getattr(self, name) for name in _STATE})
        return state
