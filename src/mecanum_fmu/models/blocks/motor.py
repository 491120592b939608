"""A DC gear motor with a PI speed loop, from its datasheet (docs/robot.md, The motor).

All values at the output shaft, at the rated voltage V_supply:
    R_a = V_supply / stall_current            k_t = stall_torque / stall_current
    k_e = (V_supply - R_a no_load_current) / no_load_speed
    b   = k_t no_load_current / no_load_speed (the no-load friction, as viscous)
so that the no-load speed and the stall torque come out exactly. A gear motor's numbers give
k_e > k_t: (k_e - k_t) i w is the gearbox's loss, kept and reported (never forced to 0).

The PI loop wants the voltage V* = kp (w_ref - w) + z; V is V* clamped so that
|V - k_e w| <= R_a i_max (the current limit: with La = 0 it is exact, with La > 0 it limits the
current the winding tends to) and then to |V| <= V_supply. Anti-windup by back-calculation:
z' = ki (w_ref - w) + k_b (V - V*), with k_b = ki / kp (the tracking time constant T_t = kp / ki,
the PI's own integral time: Astrom and Hagglund), at most the loop's natural frequency
sqrt(k_t ki / (R_a J)) (a small kp: no rate faster than the substeps already follow). While
clamped, z relaxes to the clamp at the rate k_b (with k_b kp = ki, z' = k_b (V - z)); unclamped
V = V* and z' = ki (w_ref - w). The rate is continuous in the state
(no switch in the integrator: an adaptive step meets no discontinuity where the clamp releases).

State x = (w, z, i, E_el, E_cu, E_visc, E_gear, E_load); i is a state only when La > 0 (else
the algebraic (V - k_e w)/R_a); the energies are the integrals of V i, R_a i^2, b w^2,
(k_e - k_t) i w and tau_load w, taken with the same Runge-Kutta stages as the motion.
"""
import functools
import math

DATASHEET = ("V_supply", "stall_torque", "stall_current", "no_load_speed", "no_load_current")
# Pololu 37D Metal Gearmotor, 30:1, 12 V (items #4742/#4752), 37D datasheet rev 1.2:
# no load 330 rpm at 0.2 A, stall 14 kg cm (140 kg mm) at 5.5 A (docs/robot.md).
DEFAULT_MOTOR = {"V_supply": 12.0, "stall_torque": 140.0e-3 * 9.80665,
                 "stall_current": 5.5, "no_load_speed": 330.0 * math.pi / 30.0,
                 "no_load_current": 0.2, "La": 0.0, "J": 2.0e-3,
                 "kp": 2.0, "ki": 150.0, "i_max": 5.5}
RATE_STEP = 0.05    # substeps keep (fastest rate) x (substep) at or below this: RK4 error ~1e-9


def derived(V_supply, stall_torque, stall_current, no_load_speed, no_load_current):
    """(R_a, k_t, k_e, b) from the datasheet by the standard relations."""
    R_a = V_supply / stall_current
    k_t = stall_torque / stall_current
    k_e = (V_supply - R_a * no_load_current) / no_load_speed
    return R_a, k_t, k_e, k_t * no_load_current / no_load_speed


def motor_problem(V_supply, stall_torque, stall_current, no_load_speed, no_load_current,
                  La, J, kp, ki, i_max):
    """(parameter, message) for the first value outside its range, else None."""
    values = dict(zip(DATASHEET + ("La", "J", "kp", "ki", "i_max"),
                      (V_supply, stall_torque, stall_current, no_load_speed, no_load_current,
                       La, J, kp, ki, i_max)))
    for name, value in values.items():
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return name, f"parameter {name} = {value!r} is not a finite number"
    for name in ("V_supply", "stall_torque", "stall_current", "no_load_speed", "J", "i_max"):
        if not values[name] > 0.0:
            return name, f"parameter {name} = {values[name]!r} must be > 0 (a datasheet value)"
    for name in ("La", "kp", "ki"):
        if values[name] < 0.0:
            return name, f"parameter {name} = {values[name]!r} must be >= 0"
    if not 0.0 <= no_load_current < stall_current:
        return "no_load_current", (f"parameter no_load_current = {no_load_current!r} A must be "
                                   f">= 0 and below stall_current = {stall_current!r} A")
    return None


def back_calculation(kp: float, ki: float, k_t: float, R_a: float, J: float) -> float:
    """The anti-windup's tracking gain k_b [1/s]: ki / kp (T_t = the integral time), at most
    the PI loop's natural frequency sqrt(k_t ki / (R_a J)) (which Motor.rate includes)."""
    natural = math.sqrt(k_t * ki / (R_a * J))
    return min(ki / kp, natural) if kp > 0.0 else natural


class Motor:
    """The parameters of one motor, with the derived constants."""

    def __init__(self, V_supply, stall_torque, stall_current, no_load_speed, no_load_current,
                 La, J, kp, ki, i_max):
        self.V_supply, self.La, self.J = V_supply, La, J
        self.kp, self.ki, self.i_max = kp, ki, i_max
        self.R_a, self.k_t, self.k_e, self.b = derived(
            V_supply, stall_torque, stall_current, no_load_speed, no_load_current)
        self.k_b = back_calculation(kp, ki, self.k_t, self.R_a, J)
        rate = (self.b + self.k_t * (self.k_e + kp) / self.R_a) / J + math.sqrt(
            self.k_t * ki / (self.R_a * J))
        self.rate = max(rate, self.R_a / La) if La > 0.0 else rate

    def voltage(self, w: float, z: float, w_ref: float) -> tuple[float, float]:
        """(V after the current limit and the supply clamp, the PI's wanted V*)."""
        wanted = self.kp * (w_ref - w) + z
        back = self.k_e * w
        span = self.R_a * self.i_max
        V = max(back - span, min(back + span, wanted))      # the current limit, then
        V = max(-self.V_supply, min(self.V_supply, V))      # the supply: it always wins
        return V, wanted

    def current(self, w: float, i: float, V: float) -> float:
        return i if self.La > 0.0 else (V - self.k_e * w) / self.R_a

    def rates(self, w: float, z: float, i: float, w_ref: float, tau_load: float) -> tuple:
        """The derivatives of x = (w, z, i, E_el, E_cu, E_visc, E_gear, E_load)."""
        return self._rates(w, z, i, w_ref, tau_load)

    @functools.cached_property
    def _rates(self):
        """rates() with voltage() and current() inlined and the constants bound: the same
        float operations in the same order (the same bits), without the method calls and
        attribute look-ups, which were most of a drive-train run's time."""
        kp, ki, k_b, k_t, k_e, b = self.kp, self.ki, self.k_b, self.k_t, self.k_e, self.b
        R_a, La, J, V_supply = self.R_a, self.La, self.J, self.V_supply
        span, gear, inductive = R_a * self.i_max, k_e - k_t, La > 0.0

        def rates(w, z, i, w_ref, tau_load):
            wanted = kp * (w_ref - w) + z
            back = k_e * w
            # voltage()'s max(lo, min(hi, v)), written as the builtins decide (min(a, b) is
            # b if b < a else a, max(a, b) is b if b > a else a: NaN included)
            hi, lo = back + span, back - span
            V = wanted if wanted < hi else hi
            V = V if V > lo else lo
            V = V if V < V_supply else V_supply
            V = V if V > -V_supply else -V_supply
            if inductive:
                di = (V - R_a * i - k_e * w) / La
            else:
                i, di = (V - k_e * w) / R_a, 0.0
            return ((k_t * i - b * w - tau_load) / J, ki * (w_ref - w) + k_b * (V - wanted), di,
                    V * i, R_a * i * i, b * w * w, gear * i * w, tau_load * w)
        return rates

    def step(self, x: list, w_ref: float, tau_load: float, h: float) -> list:
        """Advance the state by h with w_ref and tau_load held (classic RK4 substeps: the stages
        a + 0.5 dt k and a + dt/6 (k1 + 2 k2 + 2 k3 + k4) in scalars; the energies do not feed
        back, so only (w, z, i) go into the stages)."""
        n = max(1, math.ceil(h * self.rate / RATE_STEP))
        dt = h / n
        half, sixth, rates = 0.5 * dt, dt / 6.0, self._rates
        w, z, i, e3, e4, e5, e6, e7 = x
        for _ in range(n):
            p = rates(w, z, i, w_ref, tau_load)
            q = rates(w + half * p[0], z + half * p[1], i + half * p[2], w_ref, tau_load)
            r = rates(w + half * q[0], z + half * q[1], i + half * q[2], w_ref, tau_load)
            s = rates(w + dt * r[0], z + dt * r[1], i + dt * r[2], w_ref, tau_load)
            w, z, i, e3, e4, e5, e6, e7 = (
                w + sixth * (p[0] + 2.0 * q[0] + 2.0 * r[0] + s[0]),
                z + sixth * (p[1] + 2.0 * q[1] + 2.0 * r[1] + s[1]),
                i + sixth * (p[2] + 2.0 * q[2] + 2.0 * r[2] + s[2]),
                e3 + sixth * (p[3] + 2.0 * q[3] + 2.0 * r[3] + s[3]),
                e4 + sixth * (p[4] + 2.0 * q[4] + 2.0 * r[4] + s[4]),
                e5 + sixth * (p[5] + 2.0 * q[5] + 2.0 * r[5] + s[5]),
                e6 + sixth * (p[6] + 2.0 * q[6] + 2.0 * r[6] + s[6]),
                e7 + sixth * (p[7] + 2.0 * q[7] + 2.0 * r[7] + s[7]))
        if self.La == 0.0:
            i = self.current(w, i, self.voltage(w, z, w_ref)[0])
        return [w, z, i, e3, e4, e5, e6, e7]
