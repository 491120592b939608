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

eps is tied to a reference step h_ref, once for the run: eps = max(eps_min, eps_rate h_ref)
(the scenario layer sets h_ref to the experiment's step_size, models/catalog.py). The
wheel-floor loop runs across two FMUs at the rate (R sin alpha)^2 mu N / (eps J), so a run at
h = h_ref has (R sin alpha)^2 mu N / (eps_rate J) for its product with h, whatever step the
scenario chose; an adaptive master's trial steps and half steps step this same model
(docs/robot.md, Stability). The body's RK4 substeps follow the step: the contact rate times
the substep stays at or below RATE_STEP for any h.
"""
import math

POSITIONS = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))   # (x/L, y/W) per wheel
ROLLER_SIGNS = (-1.0, 1.0, -1.0, 1.0)
BODY = ("m", "Iz", "mu", "g", "eps_rate", "eps_min", "h_ref")
DEFAULT_BODY = {"m": 4.0, "Iz": 0.053, "mu": 1.0, "g": 9.81, "eps_rate": 40.0,
                "eps_min": 1.0e-3, "h_ref": 1.0e-3}
RATE_STEP = 0.25    # RK4 substeps keep the body's contact rate x substep at or below this


def body_problem(m, Iz, mu, g, eps_rate, eps_min, h_ref):
    """(parameter, message) for the first value outside its range, else None."""
    values = dict(zip(BODY, (m, Iz, mu, g, eps_rate, eps_min, h_ref)))
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

    def __init__(self, alpha, L, W, R, m, Iz, mu, g, eps_rate, eps_min, h_ref):
        self.m, self.Iz = m, Iz
        self.eps = max(eps_min, eps_rate * h_ref)       # the regularisation speed of the run
        self.push = mu * m * g / 4.0                    # mu N_i, the most a contact passes
        c, s = math.cos(alpha), math.sin(alpha)
        self.rim = R * s                                # the wheel's speed along u_i per rad/s
        self.axes = [(sign * c, s) for sign in ROLLER_SIGNS]
        self.arms = [(px * L, py * W) for px, py in POSITIONS]
        # (r_i x u_i): the yaw lever of each contact
        self.levers = [x * uy - y * ux for (x, y), (ux, uy) in zip(self.arms, self.axes)]
        self.stiffness = 4.0 * self.push * max(max(c * c, s * s) / m,
                                               max(a * a for a in self.levers) / Iz)

    def slips(self, vx: float, vy: float, w: float, wheels) -> list:
        return [(vx - w * y) * ux + (vy + w * x) * uy - self.rim * wi
                for (x, y), (ux, uy), wi in zip(self.arms, self.axes, wheels)]

    def forces(self, slips, eps: float) -> list:
        return [-self.push * math.tanh(s / eps) for s in slips]

    def rates(self, vx, vy, w, w1, w2, w3, w4, eps) -> tuple:
        """(vx', vy', w', slip power, power into the contacts from the wheels), written out per
        contact: the operations of slips(), forces() and the sums over the contacts, in their
        order (0.0 + ... as sum() adds), so the results are the same bit for bit."""
        (x1, y1), (x2, y2), (x3, y3), (x4, y4) = self.arms
        (ux1, uy1), (ux2, uy2), (ux3, uy3), (ux4, uy4) = self.axes
        a1, a2, a3, a4 = self.levers
        rim, push, tanh = self.rim, -self.push, math.tanh
        s1 = (vx - w * y1) * ux1 + (vy + w * x1) * uy1 - rim * w1
        s2 = (vx - w * y2) * ux2 + (vy + w * x2) * uy2 - rim * w2
        s3 = (vx - w * y3) * ux3 + (vy + w * x3) * uy3 - rim * w3
        s4 = (vx - w * y4) * ux4 + (vy + w * x4) * uy4 - rim * w4
        f1, f2, f3, f4 = (push * tanh(s1 / eps), push * tanh(s2 / eps), push * tanh(s3 / eps),
                          push * tanh(s4 / eps))
        fx = 0.0 + f1 * ux1 + f2 * ux2 + f3 * ux3 + f4 * ux4
        fy = 0.0 + f1 * uy1 + f2 * uy2 + f3 * uy3 + f4 * uy4
        torque = 0.0 + f1 * a1 + f2 * a2 + f3 * a3 + f4 * a4
        return (fx / self.m + w * vy, fy / self.m - w * vx, torque / self.Iz,
                -(0.0 + f1 * s1 + f2 * s2 + f3 * s3 + f4 * s4),
                0.0 + f1 * rim * w1 + f2 * rim * w2 + f3 * rim * w3 + f4 * rim * w4)

    def step(self, x: list, wheels, h: float) -> list:
        """Advance (vx, vy, w, E_slip, E_drive) by h with the wheel speeds held (RK4; the
        stages in scalars, as the list form a + 0.5 dt k, a + dt/6 (k1 + 2 k2 + 2 k3 + k4))."""
        eps = self.eps
        n = max(1, math.ceil(h * self.stiffness / (eps * RATE_STEP)))
        dt = h / n
        half, sixth, rates = 0.5 * dt, dt / 6.0, self.rates
        w1, w2, w3, w4 = wheels
        a, b, c, d, e = x
        for _ in range(n):
            p = rates(a, b, c, w1, w2, w3, w4, eps)
            q = rates(a + half * p[0], b + half * p[1], c + half * p[2], w1, w2, w3, w4, eps)
            r = rates(a + half * q[0], b + half * q[1], c + half * q[2], w1, w2, w3, w4, eps)
            s = rates(a + dt * r[0], b + dt * r[1], c + dt * r[2], w1, w2, w3, w4, eps)
            a, b, c, d, e = (a + sixth * (p[0] + 2.0 * q[0] + 2.0 * r[0] + s[0]),
                             b + sixth * (p[1] + 2.0 * q[1] + 2.0 * r[1] + s[1]),
                             c + sixth * (p[2] + 2.0 * q[2] + 2.0 * r[2] + s[2]),
                             d + sixth * (p[3] + 2.0 * q[3] + 2.0 * r[3] + s[3]),
                             e + sixth * (p[4] + 2.0 * q[4] + 2.0 * r[4] + s[4]))
        return [a, b, c, d, e]

    def kinetic(self, vx: float, vy: float, w: float) -> float:
        return 0.5 * self.m * (vx * vx + vy * vy) + 0.5 * self.Iz * w * w
