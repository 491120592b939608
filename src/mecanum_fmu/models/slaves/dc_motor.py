"""DCMotor FMU: one wheel's DC gear motor with a PI speed loop, parameters from a datasheet."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline
from mecanum_fmu.models.blocks.motor import DEFAULT_MOTOR, Motor, motor_problem  # inline

_PARAMETERS = tuple(DEFAULT_MOTOR) + ("w0",)
_ENERGIES = ("E_electrical", "E_copper", "E_viscous", "E_gear", "E_load")
_DERIVED = ("R_a", "k_t", "k_e", "b")
_STATE = ("w", "z", "i") + _ENERGIES
_INPUTS = ("w_ref", "tau_load")
_DOCS = {
    "w_ref": "commanded wheel speed, positive rolls the car forward",
    "tau_load": "the floor's reaction torque on the wheel (opposes positive w when positive)",
    "V_supply": "rated (supply) voltage of the datasheet; the PI output is clamped to +-V_supply",
    "stall_torque": "datasheet stall torque at V_supply, at the output shaft",
    "stall_current": "datasheet stall current at V_supply",
    "no_load_speed": "datasheet no-load speed at V_supply, at the output shaft",
    "no_load_current": "datasheet no-load current at V_supply",
    "La": "armature inductance (0: first order, the current follows the voltage at once)",
    "J": "inertia of rotor, gears and wheel about the wheel axle (all of it, here only)",
    "kp": "PI speed loop, proportional gain (volts per rad/s of speed error)",
    "ki": "PI speed loop, integral gain (volts per rad of integrated speed error)",
    "i_max": "current limit of the driver: |V - k_e w| <= R_a i_max",
    "w0": "wheel speed at the start (the PI integrator starts at the voltage that holds it)",
    "w": "wheel speed (the motor's state)",
    "i": "armature current",
    "V": "voltage applied to the armature, after the current limit and the supply clamp",
    "tau": "motor torque at the wheel, k_t i",
    "z": "PI integrator (volts)",
    "E_electrical": "electrical energy drawn since the start, integral of V i",
    "E_copper": "copper loss since the start, integral of R_a i^2",
    "E_viscous": "viscous friction loss since the start, integral of b w^2",
    "E_gear": "gearbox loss since the start, integral of (k_e - k_t) i w",
    "E_load": "work done on the floor's reaction since the start, integral of tau_load w",
    "V_clamp": "the voltage clamp in effect, V_supply (for plots and reports of the run)",
    "i_clamp": "the current limit in effect, i_max (for plots and reports of the run)",
    "R_a": "armature resistance V_supply / stall_current",
    "k_t": "torque constant at the wheel, stall_torque / stall_current",
    "k_e": "back-EMF constant at the wheel, (V_supply - R_a no_load_current) / no_load_speed",
    "b": "viscous friction k_t no_load_current / no_load_speed",
}


class DCMotor(QuickState, Fmi2Slave):
    author = "mecanum_fmu"
    description = ("DC gear motor driving one wheel, with a PI speed loop (anti-windup, current "
                   "limit i_max, voltage clamp +-V_supply); resistance, torque and back-EMF "
                   "constants and viscous friction derived from the datasheet's stall and "
                   "no-load values at V_supply. The wheel speed w is a state (no feedthrough); "
                   "V, i and tau follow w_ref at once through the PI's proportional term.")
    UNITS = {"w_ref": "rad/s", "tau_load": "N.m", "V_supply": "V", "stall_torque": "N.m",
             "stall_current": "A", "no_load_speed": "rad/s", "no_load_current": "A", "La": "H",
             "J": "kg.m2", "kp": "V.s/rad", "ki": "V/rad", "i_max": "A", "w0": "rad/s",
             "w": "rad/s", "i": "A", "V": "V", "tau": "N.m", "z": "V",
             "V_clamp": "V", "i_clamp": "A",
             "R_a": "ohm", "k_t": "N.m/A", "k_e": "V.s/rad", "b": "N.m.s/rad",
             **{name: "J" for name in _ENERGIES}}
    DEPENDENCIES = {"w": (), "i": ("w_ref",), "V": ("w_ref",), "tau": ("w_ref",),
                    **{name: () for name in _ENERGIES}, "V_clamp": (), "i_clamp": ()}
    INITIAL_DEPENDENCIES = {name: ("w_ref",) + _PARAMETERS for name in ("w", "i", "V", "tau")}
    INITIAL_DEPENDENCIES.update({name: () for name in _ENERGIES})
    INITIAL_DEPENDENCIES.update({name: tuple(DEFAULT_MOTOR)[:5] for name in _DERIVED})
    INITIAL_DEPENDENCIES.update({"V_clamp": ("V_supply",), "i_clamp": ("i_max",)})
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.001)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value in DEFAULT_MOTOR.items():
            setattr(self, name, value)
        self.w0 = self.w_ref = self.tau_load = 0.0
        for name in _STATE + ("V", "tau", "V_clamp", "i_clamp") + _DERIVED:
            setattr(self, name, 0.0)
        self._motor = None
        self._register(_INPUTS, Fmi2Causality.input, Fmi2Variability.continuous)
        self._register(_PARAMETERS, Fmi2Causality.parameter, Fmi2Variability.fixed)
        self._register(("w", "i", "V", "tau") + _ENERGIES, Fmi2Causality.output,
                       Fmi2Variability.continuous)
        self._register(("z",), Fmi2Causality.local, Fmi2Variability.continuous)
        self._register(_DERIVED, Fmi2Causality.calculatedParameter, Fmi2Variability.fixed)
        self._register(("V_clamp", "i_clamp"), Fmi2Causality.output, Fmi2Variability.discrete)

    def _register(self, names, causality, variability):
        for name in names:
            self.register_variable(Real(name, causality=causality, variability=variability,
                                        description=_DOCS[name]))

    def _start(self):
        values = [getattr(self, name) for name in DEFAULT_MOTOR]
        problem = motor_problem(*values)
        if problem is not None:
            self.log(f"DCMotor: {problem[1]}", Fmi2Status.error)
            raise ValueError(problem[1])
        self._motor = m = Motor(*values)
        self.R_a, self.k_t, self.k_e, self.b = m.R_a, m.k_t, m.k_e, m.b
        self.V_clamp, self.i_clamp = self.V_supply, self.i_max
        self.w = self.w0
        self.z = (m.k_e + m.R_a * m.b / m.k_t) * self.w0       # holds w0 without load
        self.i = m.b * self.w0 / m.k_t
        for name in _ENERGIES:
            setattr(self, name, 0.0)
        self._outputs()

    def _outputs(self):
        m = self._motor
        self.V = m.voltage(self.w, self.z, self.w_ref)[0]
        self.i = m.current(self.w, self.i, self.V)
        self.tau = m.k_t * self.i

    def enter_initialization_mode(self):
        self._start()

    def exit_initialization_mode(self):
        self._start()          # parameters may have changed during initialization

    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        if self._motor is not None:
            self._outputs()    # V, i and tau follow w_ref through the PI's proportional term

    def do_step(self, current_time, step_size):
        x = self._motor.step([getattr(self, name) for name in _STATE],
                             self.w_ref, self.tau_load, step_size)
        for name, value in zip(_STATE, x):
            setattr(self, name, value)
        self._outputs()
        return True
