"""MecanumDynamics FMU: the chassis as a planar rigid body on four free-roller contacts."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.kinematics import DEFAULT_GEOMETRY, geometry_problem  # inline
from mecanum_fmu.models.blocks.traction import BODY, DEFAULT_BODY, Chassis, body_problem  # inline

_WHEELS = ("w1", "w2", "w3", "w4")
_TWIST = ("vx", "vy", "w")
_START = ("vx0", "vy0", "w0")
_GEOMETRY = ("alpha", "L", "W", "R")
_LOADS = ("tau_load1", "tau_load2", "tau_load3", "tau_load4")
_SLIPS = ("slip1", "slip2", "slip3", "slip4")
_ENERGIES = ("E_slip", "E_drive", "E_kinetic")
_WHERE = ("front-right", "front-left", "rear-left", "rear-right")
_DOCS = {
    "alpha": "roller axis to wheel axle angle, 0 < alpha < pi/2",
    "L": "half the distance between left and right wheel centres",
    "W": "half the distance between front and rear wheel centres",
    "R": "wheel radius",
    "m": "mass of the whole robot (wheels and motors included)",
    "Iz": "yaw inertia of the whole robot about its centre",
    "mu": "floor friction coefficient along the roller axis (the rollers roll freely across it)",
    "g": "gravity; each contact carries the static load m g / 4",
    "eps_rate": "friction regularisation: eps = max(eps_min, eps_rate h_ref), fixed for the run",
    "eps_min": "smallest regularisation speed eps of the friction's tanh",
    "h_ref": "the regularisation's reference step (mecanum_fmu: the scenario's step_size)",
    "vx0": "body velocity along +X at the start", "vy0": "body velocity along +Y at the start",
    "w0": "yaw rate at the start",
    "vx": "chassis velocity along body +X (right)", "vy": "chassis velocity along body +Y (forward)",
    "w": "chassis yaw rate, counter-clockwise positive",
    "E_slip": "energy lost to sliding since the start, integral of friction force x slip speed",
    "E_drive": "work the wheels did on the contacts since the start, integral of tau_load_i w_i",
    "E_kinetic": "kinetic energy of the body, m (vx^2 + vy^2) / 2 + Iz w^2 / 2",
    "eps": "the friction's regularisation speed max(eps_min, eps_rate h_ref), fixed for the run",
}
for _i, _where in enumerate(_WHERE):
    _DOCS[_WHEELS[_i]] = f"{_where} wheel speed, positive rolls the car forward"
    _DOCS[_LOADS[_i]] = f"{_where} wheel: the floor's reaction torque on it (to its motor)"
    _DOCS[_SLIPS[_i]] = (f"{_where} contact: sliding speed along its roller axis "
                         "(0: rolling as the kinematics say)")


class MecanumDynamics(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("Planar rigid-body dynamics of a four-wheel O-layout mecanum chassis: each "
                   "wheel pushes the body along its roller axis, limited by Coulomb friction "
                   "mu m g / 4 (tanh-regularised, no memory). Inputs the wheel speeds, outputs "
                   "the body twist (a state: no feedthrough), the reaction torque on each wheel "
                   "and each contact's slip (direct feedthrough from that wheel's speed).")
    UNITS = {**{n: "rad/s" for n in _WHEELS}, "alpha": "rad", "L": "m", "W": "m", "R": "m",
             "m": "kg", "Iz": "kg.m2", "mu": "1", "g": "m/s2", "eps_rate": "m/s2",
             "eps_min": "m/s", "h_ref": "s", "eps": "m/s", "vx0": "m/s", "vy0": "m/s",
             "w0": "rad/s", "vx": "m/s", "vy": "m/s", "w": "rad/s", **{n: "N.m" for n in _LOADS},
             **{n: "m/s" for n in _SLIPS}, **{n: "J" for n in _ENERGIES}}
    DEPENDENCIES = {**{n: () for n in _TWIST + _ENERGIES + ("eps",)},
                    **{n: (w,) for n, w in zip(_LOADS + _SLIPS, _WHEELS * 2)}}
    INITIAL_DEPENDENCIES = {**{n: (s,) for n, s in zip(_TWIST, _START)},
                            **{n: () for n in _ENERGIES[:2]},
                            "E_kinetic": _START + ("m", "Iz"),
                            "eps": ("eps_rate", "eps_min", "h_ref"),
                            **{n: (w,) + _START + _GEOMETRY + BODY
                               for n, w in zip(_LOADS + _SLIPS, _WHEELS * 2)}}
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value in {**DEFAULT_GEOMETRY, **DEFAULT_BODY}.items():
            setattr(self, name, value)
        for name in _WHEELS + _START + _TWIST + _LOADS + _SLIPS + _ENERGIES:
            setattr(self, name, 0.0)
        self._chassis, self.eps = None, 0.0
        self._register(_WHEELS, Fmi2Causality.input, Fmi2Variability.continuous)
        self._register(_GEOMETRY + BODY + _START, Fmi2Causality.parameter, Fmi2Variability.fixed)
        self._register(_TWIST + _LOADS + _SLIPS + _ENERGIES, Fmi2Causality.output,
                       Fmi2Variability.continuous)
        self._register(("eps",), Fmi2Causality.output, Fmi2Variability.continuous)

    def _register(self, names, causality, variability):
        for name in names:
            self.register_variable(Real(name, causality=causality, variability=variability,
                                        description=_DOCS[name]))

    def _start(self):
        geometry = [getattr(self, n) for n in _GEOMETRY]
        body = [getattr(self, n) for n in BODY]
        problem = geometry_problem(*geometry) or body_problem(*body)
        if problem is not None:
            self.log(f"MecanumDynamics: {problem[1]}", Fmi2Status.error)
            raise ValueError(problem[1])
        self._chassis = Chassis(*geometry, *body)
        self.eps = self._chassis.eps
        self.vx, self.vy, self.w = self.vx0, self.vy0, self.w0
        self.E_slip = self.E_drive = 0.0
        self._outputs()

    def _outputs(self):
        c = self._chassis
        wheels = [getattr(self, n) for n in _WHEELS]
        slips = c.slips(self.vx, self.vy, self.w, wheels)
        for name, load, slip in zip(_LOADS, c.forces(slips, self.eps), slips):
            setattr(self, name, c.rim * load)
        for name, slip in zip(_SLIPS, slips):
            setattr(self, name, slip)
        self.E_kinetic = c.kinetic(self.vx, self.vy, self.w)

    def enter_initialization_mode(self):
        self._start()

    def exit_initialization_mode(self):
        self._start()          # parameters may have changed during initialization

    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        if self._chassis is not None:
            self._outputs()    # the reactions and slips follow the wheel speeds at once

    def do_step(self, current_time, step_size):
        c = self._chassis
        x = c.step([self.vx, self.vy, self.w, self.E_slip, self.E_drive],
                   [getattr(self, n) for n in _WHEELS], step_size)
        self.vx, self.vy, self.w, self.E_slip, self.E_drive = x
        self._outputs()
        return True
