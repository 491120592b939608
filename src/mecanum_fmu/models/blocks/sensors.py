"""Sampled sensors: sample times, reproducible noise, encoder quantisation (docs/robot.md).

Standard library only (inlined into the Encoder, Gyro and Odometry FMUs).

A sensor samples at t_k = t0 + k*period (k = 1, 2, ...). A co-simulation input is held over a
communication step, so the integral of the input (the wheel angle, the heading) is linear in
time inside a step and a sample time that falls inside a step is taken exactly there; its value
becomes visible at the end of that step. The noise of sample k is a pure function of (seed, k):
the same seed gives the same samples whatever the master's step, across a rollback (the state
to carry is the sample index) and on any worker.
"""
import math

_MASK = (1 << 64) - 1
# Salts keep the streams of two kinds of sensor apart when a user gives them the same seed.
ENCODER_SALT = 0x656E636F646572      # "encoder"
GYRO_SALT = 0x6779726F               # "gyro"
# A sample time within this many periods of a step's end counts as that step's (float slack).
_SLACK = 1e-9


def _splitmix64(z: int) -> int:
    z = (z + 0x9E3779B97F4A7C15) & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def standard_normal(seed: int, salt: int, k: int) -> float:
    """The k-th standard normal draw of the stream (seed, salt): Box-Muller on two uniforms
    from a counter-based hash (splitmix64), so draw k needs no draw before it."""
    base = _splitmix64((seed & _MASK) ^ salt)
    a = _splitmix64((base + 2 * k) & _MASK)
    b = _splitmix64((base + 2 * k + 1) & _MASK)
    u1 = ((a >> 11) + 1) * 2.0 ** -53          # (0, 1]: log(u1) is finite
    u2 = (b >> 11) * 2.0 ** -53
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


def samples_until(t0: float, period: float, next_k: int, t_end: float) -> list[int]:
    """The sample indices k >= next_k with t0 + k*period <= t_end (within float slack)."""
    last = math.floor((t_end - t0) / period + _SLACK)
    return list(range(next_k, last + 1))


def sample_time(t0: float, period: float, k: int) -> float:
    return t0 + k * period


def ticks_of(angle: float, cpr: int) -> int:
    """The count of a quadrature encoder at a wheel angle [rad] (cpr counts per revolution,
    counting down when the wheel turns back): floor(angle cpr / 2 pi)."""
    return math.floor(angle * cpr / (2.0 * math.pi))


def measured_speed(count_now: float, count_before: float, cpr: int, period: float) -> float:
    """Mean wheel speed over a sample period from two counts [rad/s]; with cpr = 0 the
    counts are the angles themselves (an ideal encoder)."""
    per_count = 2.0 * math.pi / cpr if cpr else 1.0
    return (count_now - count_before) * per_count / period


def count_of(angle: float, cpr: int) -> float:
    """What the encoder counts at an angle: the tick count, or the angle itself at cpr = 0."""
    return ticks_of(angle, cpr) if cpr else angle


def wrap_int32(count: int) -> int:
    """A 32-bit counter register: the count modulo 2^32, as a signed value (an FMI Integer)."""
    return ((int(count) + (1 << 31)) % (1 << 32)) - (1 << 31)


def sensor_problem(period: float, sigma: float):
    """(parameter, message) for a sample period or noise level outside its range, else None."""
    if not isinstance(period, (int, float)) or not math.isfinite(period) or period <= 0.0:
        return "period", (f"parameter period = {period!r} s must be a finite number > 0 "
                          "(the sample period; try 0.01)")
    if not isinstance(sigma, (int, float)) or not math.isfinite(sigma) or sigma < 0.0:
        return "sigma", (f"parameter sigma = {sigma!r} rad/s must be a finite number >= 0 "
                         "(the noise standard deviation per sample; 0: no noise)")
    return None


def encoder_problem(cpr: int, period: float, sigma: float):
    """sensor_problem, and cpr >= 0 (0: an ideal encoder, no quantisation)."""
    if isinstance(cpr, bool) or not isinstance(cpr, int) or cpr < 0:
        return "cpr", (f"parameter cpr = {cpr!r} must be a whole number >= 0 (counts per "
                       "wheel revolution, e.g. 4096; 0: no quantisation)")
    return sensor_problem(period, sigma)


def gyro_problem(period: float, sigma: float, bias: float):
    """sensor_problem, and a finite bias."""
    if isinstance(bias, bool) or not isinstance(bias, (int, float)) or not math.isfinite(bias):
        return "bias", f"parameter bias = {bias!r} rad/s must be a finite number"
    return sensor_problem(period, sigma)


def check_sensor(problem) -> None:
    """Raise ValueError with the message of a (parameter, message) problem, if any."""
    if problem is not None:
        raise ValueError(problem[1])
