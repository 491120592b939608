"""Bicycle FMU: the car-like robot as a kinematic bicycle, (v, phi) -> body twist of a reference point."""
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.bicycle import bicycle_twist, check_bicycle  # inline
from mecanum_fmu.models.blocks.kinematics import instantaneous_center  # inline

_INPUTS = ("v", "phi")
_TWIST = ("vx", "vy", "w")
_ICR = ("icr_x", "icr_y", "has_icr")


class Bicycle(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Car-like robot as a kinematic bicycle: rear-axle speed v and steering angle "
                   "phi (positive turns left, counter-clockwise) -> body twist (vx right, vy "
                   "forward, w counter-clockwise) of the rear-axle (reference 0) or front-axle "
                   "(reference 1) midpoint, and its instantaneous centre of rotation (on the "
                   "rear-axle line). Direct feedthrough.")
    UNITS = {"v": "m/s", "phi": "rad", "l": "m", "vx": "m/s", "vy": "m/s", "w": "rad/s",
             "icr_x": "m", "icr_y": "m"}
    DEPENDENCIES = {name: _INPUTS for name in _TWIST + _ICR}
    INITIAL_DEPENDENCIES = {name: _INPUTS + ("l", "reference") for name in _TWIST + _ICR}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.v = self.phi = 0.0
        self.l, self.reference = 0.5, 0
        self.vx = self.vy = self.w = self.icr_x = self.icr_y = 0.0
        self.has_icr = False
        docs = {"v": "rear-axle speed, positive forward",
                "phi": "steering angle of the front wheel, positive turns left (counter-clockwise)"}
        for name in _INPUTS:
            self.register_variable(Real(name, causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description=docs[name]))
        self.register_variable(Real("l", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed,
                                    description="wheelbase, rear axle to front axle"))
        self.register_variable(Integer("reference", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed,
                                       description="the point whose twist is output: 0 rear-axle "
                                                   "midpoint, 1 front-axle midpoint"))
        out_docs = {"vx": "velocity of the reference point along body +X (right)",
                    "vy": "velocity of the reference point along body +Y (forward)",
                    "w": "yaw rate, counter-clockwise positive (v tan(phi) / l)",
                    "icr_x": "instantaneous centre of rotation, body X from the reference "
                             "point (-vy/w); 0 without one",
                    "icr_y": "instantaneous centre of rotation, body Y from the reference "
                             "point (vx/w); 0 without one"}
        for name in _TWIST + _ICR[:2]:
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous,
                                        description=out_docs[name]))
        self.register_variable(Boolean("has_icr", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       description="true when |w| >= 1e-9 rad/s (the car "
                                                   "turns), so the ICR exists"))

    def _update(self):
        # Direct feedthrough: outputs follow the inputs at once, no step needed.
        self.vx, self.vy, self.w = bicycle_twist(self.v, self.phi, self.l, self.reference)
        self.icr_x, self.icr_y, self.has_icr = instantaneous_center(self.vx, self.vy, self.w)

    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        try:
            self._update()
        except ValueError as err:
            self.log(f"Bicycle: {err}", Fmi2Status.error)
            raise
        except (ArithmeticError, TypeError):
            pass  # invalid l: reported by enter_initialization_mode

    def enter_initialization_mode(self):
        try:
            check_bicycle(self.l, self.reference)
            self._update()
        except ValueError as err:
            self.log(f"Bicycle: {err}", Fmi2Status.error)
            raise

    def exit_initialization_mode(self):
        self.enter_initialization_mode()

    def do_step(self, current_time, step_size):
        return True
