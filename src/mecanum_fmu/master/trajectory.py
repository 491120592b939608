"""The adaptive master's whole-step trajectory: the run's error carried through the dynamics.

The embedded pair (adaptive.py) takes each step once whole and once as two halves from the
same state, and keeps the halves: their difference is the step's own error, for the
controller. Summed, those errors are the error as if each were kept; where the states relax
(a motor's speed loop, a body on its contacts) the dynamics damp what earlier steps made and
the sum stays. This trajectory is the run stepped on the accepted steps, whole, from its own
states and its own inputs' history (a second set of FMU states, saved and restored with
fmi2GetFMUstate / fmi2SetFMUstate): the difference of the two trajectories, over 3 (an error
in h^2 over the run), is the kept run's error, carried, damped and fed round the loops as the
dynamics carry them. It is the estimate reported; the controller keeps the pair's own.

An input whose source steps later (a loop: its value at t_k+1 is not known when its FMU
steps) takes the kept run's value at t_k+1 plus the two trajectories' difference at t_k.
"""
from __future__ import annotations

import ctypes

import numpy as np

from .stepping import free_states, one_pass, restore_states, save_states


def slot_positions(slots) -> dict[int, int]:
    """{buffer slot: its index} of the recorded outputs an estimate covers, for values_at."""
    return {int(slot): i for i, slot in enumerate(slots)}


def values_at(positions: dict[int, int], values: np.ndarray, slots) -> np.ndarray:
    """values (one per covered output) at the given buffer slots, 0 where a slot has none."""
    at = [positions.get(int(slot)) for slot in slots]
    return np.array([0.0 if i is None else values[i] for i in at])


class WholeSteps:
    """The whole-step trajectory beside the kept run: its FMU states at t_k, its inputs'
    history per blend, and its difference from the kept run per recorded output."""

    def __init__(self, running: list, program: list, blends: list, real: np.ndarray,
                 ints: np.ndarray, slots: np.ndarray, divisor: float = 3.0):
        self.running, self.program, self.blends = running, program, blends
        self.divisor = divisor      # 2^p - 1 (AdaptiveHolds.richardson)
        self.real, self.ints, self.slots = real, ints, slots
        self.states: list | None = None         # None: at t0 it is the run's own state
        self.history = [b.history.copy() for b in blends]
        self.difference = np.zeros(len(slots))
        # the steps' errors where an FMU's response bends inside them (adaptive._Loop._bent),
        # summed: the trajectory's held means do not make them, and nothing damps them here
        self.bends = np.zeros(len(slots))
        self.positions = slot_positions(slots)

    def step(self, t: float, h: float) -> None:
        """Move it over the step just accepted (t -> t + h). The FMUs are at the kept run's
        t + h, their saved state (RunningInstance.state) the kept run's t; they are left as
        they were, with the buffers."""
        kept = [ctypes.c_void_p() for _ in self.running]
        save_states(self.running, t + h, kept)
        values = (self.real.copy(), self.ints.copy())
        restore_states(self.running, t, self.states)
        fine = self._swap_in()
        self._kinks(self.divisor)
        one_pass(self.program, t, h)
        self._kinks(0.0)
        np.subtract(self.real[self.slots], values[0][self.slots], out=self.difference)
        self._swap_out(fine)
        if self.states is not None:
            free_states(self.running, t, self.states)
        else:
            self.states = [ctypes.c_void_p() for _ in self.running]
        save_states(self.running, t + h, self.states)
        restore_states(self.running, t + h, kept)
        free_states(self.running, t + h, kept)
        self.real[:], self.ints[:] = values

    def close(self, t: float) -> None:
        """Free its FMU states (the run is over)."""
        if self.states is not None:
            free_states(self.running, t, self.states)
            self.states = None

    def now(self) -> np.ndarray:
        """The kept run's signed error per recorded output: the difference over 2^p - 1 (3:
        second order), plus the bends' errors."""
        return self.difference / self.divisor + self.bends

    def error(self) -> np.ndarray:
        """|the kept run's error| per recorded output."""
        return np.abs(self.now())

    def signed(self, slots) -> np.ndarray:
        """The kept run's signed error at the given buffer slots now (0 where it has none)."""
        return values_at(self.positions, self.now(), slots)

    def _kinks(self, share: float) -> None:
        """Its held means take `share` x their estimated error where it is large against the
        step's change (adaptive_holds._VarBlend.next: a kink among an input's values), so that
        the difference over the divisor carries the kept run's error there too."""
        for b in self.blends:
            b.holds.kinks = share

    def _swap_in(self) -> list:
        """The blends take this trajectory's history; the later sources' values are shifted
        by the difference at t_k. Returns the kept run's histories."""
        fine = []
        for b, mine in zip(self.blends, self.history):
            fine.append(b.history.copy())
            m = len(b.src)
            b.shift = np.where(b.ahead | b.fed, mine[m:2 * m] - b.history[m:2 * m], 0.0)
            b.history[:] = mine
        return fine

    def _swap_out(self, fine: list) -> None:
        """Its history moves on a step (u_k+1 its own end values); the kept run's is back."""
        for b, mine, kept in zip(self.blends, self.history, fine):
            m = len(b.src)
            mine[2 * m:] = mine[m:3 * m].copy()
            mine[m:2 * m] = b.buffer[b.src]
            b.history[:] = kept
            b.shift = None
