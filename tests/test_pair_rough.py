"""pair_rough.py: which held values are not smooth curves at the step, from their fourth
differences against their first (smooth pieces only), on series whose shape is known."""
import numpy as np

from mecanum_fmu.master.pair_rough import Roughness

T = np.arange(0.0, 6.0 + 1e-9, 0.1)       # 61 rows, 60 steps of 0.1


def _rough(columns: np.ndarray, starts=(0,), ends=(60,), lag: int = 0, chunk: int = 61):
    """The rough columns of `columns` (rows x columns), fed in chunks as PairRows feeds
    them (the window keeps every row here)."""
    n = len(columns) - 1
    tally = Roughness({lag: list(range(columns.shape[1]))}, np.array(starts), np.array(ends),
                      n, columns.shape[1])
    for first in range(0, len(columns), chunk):
        tally.tally(columns[:first + chunk], 0, first, len(columns[first:first + chunk]))
    return tally.rough(np.abs(columns).max(axis=0), n).tolist()


def test_a_staircase_is_rough_and_smooth_curves_are_not():
    stairs = np.cos(0.2 * np.floor(T / 0.2 + 1e-9))     # moves every second row
    columns = np.column_stack((np.cos(T), stairs, np.cos(10 * T), np.cos(25 * T)))
    # cos t and cos 10t (a radian a step) are curves at this step; cos 25t is not
    assert _rough(columns) == [1, 3]
    assert _rough(columns, chunk=7) == [1, 3]           # the same, chunk by chunk


def test_round_off_and_known_jumps_are_not_rough():
    flat = 0.3 + 1e-17 * np.cos(40 * T)                 # a constant with round-off in it
    jump = np.where(T < 3.0 - 1e-9, np.cos(T), np.cos(T) + 1.0)
    columns = np.column_stack((flat, jump))
    assert _rough(columns) == []                          # a jump alone is not a staircase
    # a staircase whose every step is a known breakpoint: its pieces hold one value each
    stairs = np.floor(T / 0.5 + 1e-9)[:, None]
    ends = np.arange(4, 60, 5).tolist() + [60]
    assert _rough(stairs) == [0]
    assert _rough(stairs, starts=[0] + [e + 1 for e in ends[:-1]], ends=ends) == []


def test_a_curve_too_fast_for_the_step_is_rough():
    # about (h omega)^3 for a curve: a cosine at 3 radians a step is past ROUGH, at 2 not
    assert _rough(np.cos(30 * T)[:, None]) == [0]
    assert _rough(np.cos(20 * T)[:, None]) == []


def test_a_staircase_of_one_or_two_rows_a_stair_is_rough_by_its_holds(monkeypatch):
    """Stairs of 0.13 s at 0.1 s steps: each value is held for one row or two, and the
    fourth differences sum to 2.5x the first, under ROUGH (the bouncing ball's kinks sum to
    2 to 3). A value held to the bit between two moves tells it. A kinked curve (|sin 2t|),
    one that saturates (long holds, not between moves every few rows) and one at rest
    before it moves hold none that way."""
    from mecanum_fmu.master import pair_rough
    stairs = np.cos(0.13 * np.floor(T / 0.13 + 1e-9))
    kinked, saturated = np.abs(np.sin(2 * T)), np.clip(np.cos(T), -0.5, 0.5)
    resting = np.where(T < 2.0, 0.2, 0.2 + np.sin(T - 2.0))
    columns = np.column_stack((stairs, kinked, saturated, resting))
    assert _rough(columns) == [0]
    assert _rough(columns, chunk=7) == [0]
    monkeypatch.setattr(pair_rough, "HELD_LEAST", np.inf)       # the sums alone
    assert _rough(columns) == []


def test_values_whose_ratio_does_not_grow_over_every_second_row_are_rough(monkeypatch):
    """Over every second row a curve's sum of fourth differences against its first grows
    as h^3 (8x), a kink's as h (2x), many small jumps' not at all: cos t quantized to 0.005
    at 0.01 s (its ratio 1.2 at h, under ROUGH; 0.53 of it at 2h) is rough; a single unknown
    jump on a curve (its ratio 1.6 at h and at 2h: it is one), kinks (|sin 2t|, a saturation)
    and a curve are not, nor an odd-even ringing (which the subsample drops: a ratio that
    falls under NOISY_LOW)."""
    from mecanum_fmu.master import pair_rough
    t = np.arange(0.0, 6.0 + 1e-9, 0.01)
    quantized = 0.005 * np.floor(np.cos(t) / 0.005 + 0.5)
    jump = np.cos(t) + np.where(t > 2.955, 1.0, 0.0)
    kinks = np.column_stack((np.abs(np.sin(2 * t)), np.clip(np.cos(2 * t), -0.5, 0.5)))
    columns = np.column_stack((quantized, jump, kinks, np.cos(3 * t)))
    assert _rough(columns, ends=(600,)) == [0]
    assert _rough(columns, ends=(600,), chunk=13) == [0]
    ringing = np.cos(T) + 0.02 * (-1.0) ** np.arange(len(T)) * np.exp(-T)
    assert _rough(ringing[:, None]) == []
    monkeypatch.setattr(pair_rough, "NOISY", 0.0)       # the ratio at h alone
    assert _rough(columns, ends=(600,)) == []
