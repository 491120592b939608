"""The chassis as a planar rigid body on four free-roller contacts (docs/robot.md, The floor).

Body frame as in kinematics.py (+X right, +Y forward, w counter-clockwise); wheels 1 front-right
at (L, W), 2 front-left (-L, W), 3 rear-left (-L, -W), 4 rear-right (L, -W). Wheel i's roller
axis at the contact is u_i = (s_i cos(alpha), sin(alpha)), s = (-1, +1, -1, +1): the rollers
turn freely across it, so the floor pushes the body only along u_i. The contact slides along
u_i at

    slip_i = (v + w x r_i) . u_i - R sin(alpha) w_i,

zero exactly when the wheel speeds are the inverse kinematics of the twist. The floor's force
on the body along u_i is F_i = -mu N_i tanh(slip_i / eps) (N_i = m g / 4, the static load), the
wheel feels tau_load_i = R sin(alpha) F_i, and the slip loses F_i slip_i... with the sign:
-F_i slip_i = mu N_i slip_i tanh(slip_i / eps) >= 0, exactly force times sliding speed. The
tanh has no memory, so a rollback (fmi2SetFMUstate) needs only the twist.

eps is tied to the communication step h, eps = max(eps_min, eps_rate h): the wheel-floor loop
runs across two FMUs at the rate (R sin alpha)^2 mu N / (eps J), so its product with h is
(R sin alpha)^2 mu N / (eps_rate J), the same at every step size (docs/robot.md, Stability).
"""
import math

POSITIONS = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))   # (x/L, y/W) per wheel
ROLLER_SIGNS = (-1.0, 1.0, -1.0, 1.0)
BODY = ("m", "Iz", "mu", "g", "eps_rate", "eps_min")
DEFAULT_BODY = {"m": 4.0, "Iz": 0.053, "mu": 1.0, "g": 9.81, "eps_rate": 40.0,
                "eps_min": 1.0e-3}
RATE_STEP = 0.25    # RK4 substeps keep the body's contact rate x substep at or below this


def body_problem(m, Iz, mu, g, eps_rate, eps_min):
    """(parameter, message) for the first value outside its range, else None."""
    values = dict(zip(BODY, (m, Iz, mu, g, eps_rate, eps_min)))
    for name, value in values.items():
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return name, f"parameter {name} = {value!r} is not a finite number"
        if not value > 0.0 and name != "mu":
            return name, f"parameter {name} = {value!r} must be > 0"
    if mu < 0.0:
        return "mu", f"parameter mu = {mu!r} must be >= 0 (0: ice, no traction)"
    return None


class Chassis:
    """A mecanum body with its contacts: the maths of one MecanumDynamics instance."""

    def __init__(self, alpha, L, W, R, m, Iz, mu, g, eps_rate, eps_min):
        self.m, self.Iz, self.eps_rate, self.eps_min = m, Iz, eps_rate, eps_min
        self.push = mu * m * g / 4.0                    # mu N_i, the most a contact passes
        c, s = math.cos(alpha), math.sin(alpha)
        self.rim = R * s                                # the wheel's speed along u_i per rad/s
        self.axes = [(sign * c, s) for sign in ROLLER_SIGNS]
        self.arms = [(px * L, py * W) for px, py in POSITIONS]
        # (r_i x u_i): the yaw lever of each contact
        self.levers = [x * uy - y * ux for (x, y), (ux, uy) in zip(self.arms, self.axes)]
        self.stiffness = 4.0 * self.push * max(max(c * c, s * s) / m,
                                               max(a * a for a in self.levers) / Iz)

    def eps(self, h: float) -> float:
        return max(self.eps_min, self.eps_rate * h)

    def slips(self, vx: float, vy: float, w: float, wheels) -> list:
        return [(vx - w * y) * ux + (vy + w * x) * uy - self.rim * wi
                for (x, y), (ux, uy), wi in zip(self.arms, self.axes, wheels)]

    def forces(self, slips, eps: float) -> list:
        return [-self.push * math.tanh(s / eps) for s in slips]

    def rates(self, x: list, wheels, eps: float) -> list:
        """(vx', vy', w', slip power, power into the contacts from the wheels)."""
        vx, vy, w = x[0], x[1], x[2]
        slips = self.slips(vx, vy, w, wheels)
        forces = self.forces(slips, eps)
        fx = sum(f * ux for f, (ux, _) in zip(forces, self.axes))
        fy = sum(f * uy for f, (_, uy) in zip(forces, self.axes))
        torque = sum(f * a for f, a in zip(forces, self.levers))
        return [fx / self.m + w * vy, fy / self.m - w * vx, torque / self.Iz,
                -sum(f * s for f, s in zip(forces, slips)),
                sum(f * self.rim * wi for f, wi in zip(forces, wheels))]

    def step(self, x: list, wheels, h: float) -> list:
        """Advance (vx, vy, w, E_slip, E_drive) by h with the wheel speeds held (RK4)."""
        eps = self.eps(h)
        n = max(1, math.ceil(h * self.stiffness / (eps * RATE_STEP)))
        dt = h / n
        for _ in range(n):
            k1 = self.rates(x, wheels, eps)
            k2 = self.rates([a + 0.5 * dt * b for a, b in zip(x, k1)], wheels, eps)
            k3 = self.rates([a + 0.5 * dt * b for a, b in zip(x, k2)], wheels, eps)
            k4 = self.rates([a + dt * b for a, b in zip(x, k3)], wheels, eps)
            x = [a + dt / 6.0 * (p + 2.0 * q + 2.0 * r + s)
                 for a, p, q, r, s in zip(x, k1, k2, k3, k4)]
        return x

    def kinetic(self, vx: float, vy: float, w: float) -> float:
        return 0.5 * self.m * (vx * vx + vy * vy) + 0.5 * self.Iz * w * w
