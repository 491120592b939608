"""The measured response of an FMU with a state and no error model (master/probe.py): its
moment against quadrature, its model against the convolution it stands for, the fit's check,
and the probes' schedule."""
import numpy as np
import pytest
from scipy.integrate import quad

from mecanum_fmu.master.probe import PROBE_EVERY, Prober
from mecanum_fmu.master.probed_model import ProbedModel
from mecanum_fmu.master.probe_fit import Moments, bend, fitted, moment


@pytest.mark.parametrize("r", [0.05, 0.5, 0.9, 0.99999, 1.0, 1.3])
def test_the_moment_is_the_first_order_weight_by_quadrature(r):
    z = np.log(r)
    weight = lambda t: np.exp(z * (1 - t))        # noqa: E731  x' = a x + b u, s = t h
    ramp = quad(lambda t: weight(t) * (t - 0.5), 0, 1)[0]
    mean = quad(weight, 0, 1)[0]
    assert moment(np.array([[r]]))[0, 0] == pytest.approx(ramp / mean, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize("r", [0.05, 0.5, 0.99999, 1.0, 1.3, np.exp(-20.0)])
def test_the_bend_is_the_first_order_weight_of_the_parabola_by_quadrature(r):
    z = np.log(r)
    weight = lambda t: np.exp(z * (1 - t))        # noqa: E731
    square = quad(lambda t: weight(t) * ((t - 0.5) ** 2 - 1 / 12), 0, 1, points=[1.0])[0]
    mean = quad(weight, 0, 1, points=[1.0])[0]
    assert bend(np.array([[r]]))[0, 0] == pytest.approx(square / mean, rel=1e-6, abs=1e-12)


def test_a_ratio_that_is_not_positive_has_no_moment():
    assert moment(np.array([[0.0, -0.4]])).tolist() == [[0.0, 0.0]]


def _model(found):
    model = ProbedModel("f", ["a", "b"], ["y"])
    model.found = found
    return model


def _probe(k, g0, g1, r, within=0.0):
    """A first-order probe; `within` of its g0 a faster mode's part, gone within the step,
    its moment that of r plus 0.4 (probe_fit.fast_moments)."""
    g0, g1, r = (np.array(v, dtype=float).reshape(1, 2) for v in (g0, g1, r))
    fast = np.full((1, 2), within)
    return (k, 0.1, g0, g1, r, Moments(moment(r), bend(r), fast, moment(r) + 0.4,
                                       np.full((1, 2), 0.15)), np.zeros((1, 2)))


def _convolution(found, h, error, change, bent):
    """y_k = (g0_k - f_k) d_k + f_k q_k + sum_(i<k) g1_i d_i r_(i+1) ... r_(k-1), d and q the
    hold's error less the pole's and the fast part f's moment's share of the change and
    their bend's of `bent`: an error made at step i
    (d_i, with the probe in effect there) decays by the ratio of the probe in effect at each
    later step; a sum of products, one term at a time."""
    n = len(h)
    at = lambda i: [f for f in found if f[0] <= i][-1]      # noqa: E731
    y = np.zeros(n)
    for i in range(n):
        _, size, g0, g1, r, m, _ = at(i)
        d = error[i] - m.carried[0] * change[i] - 6 * m.bent[0] * bent[i]
        q = error[i] - m.quick[0] * change[i] - 6 * m.quick_bent[0] * bent[i]
        y[i] += float(np.sum((g0[0] - m.fast[0]) * d + m.fast[0] * q))
        gain = g1[0] * d
        for k in range(i + 1, n):
            y[k] += float(np.sum(gain))
            gain = gain * at(k)[4][0]
    return y


def test_the_model_is_the_sum_it_stands_for_in_any_batches():
    rng = np.random.default_rng(7)
    found = [_probe(0, [0.09, 0.02], [0.08, 0.03], [0.9, 1.0]),
             _probe(20, [0.1, 0.01], [0.07, 0.01], [0.8, 0.95], within=0.03)]
    n = 50
    h = np.full(n, 0.1)
    error, change, bent = (rng.normal(size=(n, 2)) for _ in range(3))
    want = _convolution(found, h, error, change, bent)
    lead = (0.5 * change, 0.5 * change, bent)       # (no direct part: the first two unread)
    whole = _model(found).steps(h, None, error, change, lead=lead)[:, 0]
    model = _model(found)
    parts = np.concatenate([model.steps(h[a:b], None, error[a:b], change[a:b],
                                        lead=tuple(x[a:b] for x in lead))[:, 0]
                            for a, b in ((0, 7), (7, 33), (33, 50))])
    assert np.allclose(whole, want, rtol=1e-12, atol=1e-14)
    assert np.allclose(parts, want, rtol=1e-12, atol=1e-14)


def test_the_loop_and_lfilter_carry_the_same_bits(monkeypatch):
    """Short batches are carried by a loop (no scipy.signal import, 1.6 s), long ones by
    lfilter: the same recursion, the same floating-point operations, so the same bits."""
    from mecanum_fmu.master import probe_fit
    rng = np.random.default_rng(3)
    found = [_probe(0, [0.09, 0.02], [0.08, 0.03], [0.9, -0.4]),
             _probe(30, [0.1, 0.01], [0.07, 0.01], [1.02, 0.0])]
    h, error, change = np.full(80, 0.1), rng.normal(size=(80, 2)), rng.normal(size=(80, 2))
    looped = _model(found).steps(h, None, error, change)
    monkeypatch.setattr(probe_fit, "LOOP_MAX", 0)
    filtered = _model(found).steps(h, None, error, change)
    assert np.array_equal(looped, filtered) and np.abs(looped).max() > 0.1


def test_a_first_order_response_fits_and_two_integrators_do_not():
    h, r = 0.1, np.exp(-2.0 * 0.1)
    g = np.array([(1 - r) / 2 * r ** n for n in range(4)]).reshape(4, 1, 1)   # a lag
    g0, g1, ratio, m, _ = fitted(g, np.full((1, 1), 1e-15))
    assert ratio[0, 0] == pytest.approx(r) and g1[0, 0] == pytest.approx(r * g0[0, 0])
    double = np.array([0.5, 1.5, 2.5, 3.5]).reshape(4, 1, 1) * h * h          # x'' = u
    assert "is not of first order" in fitted(double, np.full((1, 1), 1e-15))


class _Target:
    """Stands for probe.Target: each probe finds what `finds(k)` says."""

    def __init__(self, finds):
        self.model, self.finds, self.probed = ProbedModel("f", ["u"], ["y"]), finds, []
        self.steps, self.calls = 4, 0       # doStep calls per probe and input, in all

    def probe(self, k, t, h, real, room):
        self.probed.append(k)
        self.calls += self.steps * 2
        self.model.found.append(_one(k, self.finds(k)))


def _one(k, found):
    gain, r = found if isinstance(found, tuple) else (found, 0.9)
    a = np.full((1, 1), gain)
    return (k, 0.1, a, a, np.full((1, 1), r), a, np.zeros((1, 1)))


def _schedule(finds, n):
    target = _Target(finds)
    prober = Prober([target], np.zeros(1), n)
    for k in range(n):
        if k in prober.at:
            prober(k, 0.1 * k, 0.1)
    return target.probed


def test_probes_that_agree_widen_their_gap_fourfold_and_others_keep_it():
    # a probe steps 4 times: the last may start at step n - 5; the gaps 32, 128, 512, ...
    assert _schedule(lambda k: 1.0, 1000) == [0, 32, 160, 672]
    assert _schedule(lambda k: 1.0, 676) == [0, 32, 160]
    assert _schedule(lambda k: 1.0, 677) == [0, 32, 160, 672]
    # a response that changes: probed every 32 steps, and once more at the last step a
    # probe fits (195), which the end's estimate reads
    assert _schedule(lambda k: 1.0 + k / 100, 200) == [*range(0, 196, PROBE_EVERY), 195]
    assert _schedule(lambda k: 1.0, 4) == []


def test_probes_compare_a_pole_by_its_rate():
    # r 0.990 and 0.988 are 0.2% apart, their rates (ln r) 20%: the gap does not widen; a
    # rate that moves by 1e-9 (an integrator's round-off, r = 1) is the same over any gap
    changing = lambda k: (1.0, np.exp(-0.1 * (1 + k / 160)))      # noqa: E731
    assert _schedule(changing, 200) == [*range(0, 196, PROBE_EVERY), 195]
    still = lambda k: (1.0, 1.0 - 1e-9 * (k % 2))                   # noqa: E731
    assert _schedule(still, 1000) == [0, 32, 160, 672]


def test_a_probe_whose_outputs_are_not_finite_hands_over():
    # a nudged input that makes the FMU overflow: no model from it, the pair hands over
    from mecanum_fmu.master.probe import Target

    class Bare(Target):
        def __init__(self):
            self.model = ProbedModel("lag", ["u"], ["x"])
            self.r = type("R", (), {"name": "lag"})()

    target = Bare()
    runs = np.ones((2, 4, 1))
    runs[1, 2, 0] = np.inf
    target._fit(0, 0.1, runs, np.array([1e-6]))
    assert target.model.found == [] and "not finite" in target.model.failed
