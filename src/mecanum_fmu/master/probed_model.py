"""The measured response's model over the run's rows (probe.py measures it, probe_fit.py fits
each probe): the embedded pair's batch error model of an FMU with a state and no model of its
own. Each run of steps served by one probe carries the held inputs' errors through that
probe's pole (or two poles' modes) and direct part; the probes before the rows a batch
reaches are dropped as it goes (memory flat)."""
from __future__ import annotations

import numpy as np

from .pair_stencils import with_branch
from .probe_fit import carried, first_order, modal_linear, modal_outputs, within_step

REAL = ("Real", "Float64")      # FMI 2, FMI 3


def probeable(inst) -> bool:
    """Whether the FMU can be probed: FMI 2 or 3, and it says it can save its state."""
    return inst.model.fmiVersion in ("2.0", "3.0") and inst.can_get_set_state


def probed_model(inst, inputs: list[str]) -> "ProbedModel | None":
    """The ProbedModel of an FMU with a state and no error model, held inputs `inputs`: it
    covers its Real outputs (those a held input reaches directly too: their direct part,
    ProbedModel; an output whose dependencies are not declared may depend on every input,
    as FMI 2.0 says); None where it cannot be probed (probeable)."""
    if not probeable(inst):
        return None
    real = [u for u in inst.model.outputs if u.variable.type in REAL]
    direct = np.array([[u.dependencies is None or n in {d.name for d in u.dependencies}
                        for n in inputs] for u in real], dtype=bool).reshape(len(real),
                                                                            len(inputs))
    model = ProbedModel(inst.name, inputs, [u.variable.name for u in real], direct)
    model.undeclared = len(real) == len(inst.model.outputs) and all(
        u.dependencies is None for u in real)       # memory.advice: a scenario may say them
    return model


class ProbedModel:
    """The batch error model (the pair's interface: `outputs`, steps(h, held, error,
    change) -> the signed accumulated error of each output after each step) of one FMU
    whose response a Target measures while the run steps. Per probe, in `found`: (its step,
    its step size, g0, g1, r, m, D), each (outputs x inputs), and with two poles their
    modes (probe_fit.fitted; carried by _modal). Where a held input reaches an
    output directly (`direct`, its declared dependencies), the output's response within the
    step is its state's, g1 / r, and the rest, D = g0 - g1 / r, its direct part, which errs
    by the held value against the input's true end value: D (error - change / 2) on that
    row alone (none where the master holds the newest value; Jacobi's value of t_k)."""

    branches = True     # steps() and linear() take a branch (PairRows._branchable)

    def __init__(self, name: str, inputs: list[str], outputs: list[str],
                 direct: np.ndarray | None = None):
        self.name, self.inputs, self.outputs = name, inputs, outputs
        self.direct = np.zeros((len(outputs), len(inputs)), dtype=bool) if direct is None \
            else direct
        self.found: list[tuple] = []
        self.failed: str | None = None
        self.deaf = False   # failed as an input moved no output in a probe (_DEAF)
        self.undeclared = False     # every output Real, its dependencies not declared
        # (output, input): a direct part the output does not show for the input set after
        # the step (worked out in doStep alone: lazy())
        self.lazy = np.zeros((len(outputs), len(inputs)), dtype=bool)
        self.k = 0                  # the next step steps() works out
        self.s = np.zeros((len(outputs), len(inputs)))      # run - true, past steps' share

    def steps(self, h: np.ndarray, held: np.ndarray, error: np.ndarray, change: np.ndarray,
              branch: int = 0, lead: tuple | None = None) -> np.ndarray:
        """The signed error of each output after each step. `lead`: per step and input, what
        the direct part errs by less error (pair_holds.lead_of): the true input's end value
        less its mean, so that it errs by the held value against the true end value (for an
        input held "through", the hold's own error), and that end less the mean alone, for
        a `lazy` output (it reads the value held during the step); None: half the change,
        which is that only to the trapezoid's h^2 u'' / 12 (a controller that reads its
        newest input exactly read 2.5e-3 at 0.1 s on cos t); third, the true input's (start +
        end) / 2 - mean, which the moments' second terms weigh (probe_fit.bend)."""
        lead, late, bent = (0.5 * change, 0.5 * change, 0.0 * change) if lead is None \
            else lead
        miss = error - lead
        if self.lazy.any():     # the lazy parts' miss, after the others', same rows
            miss = np.concatenate((miss, error - late), axis=1)
        n = len(h)
        if not self.found or not len(self.outputs):     # finish() says why (no probe)
            self.k += n - branch
            return np.zeros((n, len(self.outputs)))
        if branch:      # the last rows another version of those before them: from before
            split = n - 2 * branch
            bulk, these, other = ((h[at], error[at], change[at], miss[at], bent[at]) for at
                                  in (slice(0, split), slice(split, n - branch),
                                      slice(n - branch, n)))
            out, s = self._run(*bulk, s=self.s, k=self.k)
            these, kept = self._run(*these, s=s, k=self.k + split)
            other, _ = self._run(*other, s=s, k=self.k + split)
            out, self.s = np.concatenate((out, these, other)), kept
        else:
            out, self.s = self._run(h, error, change, miss, bent, s=self.s, k=self.k)
        self.k += n - branch
        self._forget()
        return out

    def _run(self, h: np.ndarray, error: np.ndarray, change: np.ndarray, miss: np.ndarray,
             bent: np.ndarray, s: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Steps k .. k + len(h) - 1 from the past steps' share s: (the signed error of each
        output after each, the share after the last); `miss`: the held value against the
        true end value, which the direct part errs by; `bent`: steps()'."""
        out = np.zeros((len(h), len(self.outputs)))
        s = s.copy()
        for part, probe in self._segments(h, k) if len(h) else ():
            _, size, g0, g1, r, m, d_part, *modes = self.found[probe]
            scale = float(h[part.start]) / size
            out[part] += miss[part] @ self._split(d_part).T
            shape = (error[part], change[part], bent[part])
            if m.fast.any():        # a faster mode's part, gone within the step
                out[part] += np.einsum("oj,koj->ko", m.fast * scale,
                                       _weighed(*shape, m.quick, m.quick_bent))
            if modes:
                s = _modal(modes[0], scale, shape, out[part], s, len(h) * s.size)
                continue
            decay = np.where(r > 0, np.abs(r) ** scale, r)
            d = _weighed(*shape, m.carried, m.bent)
            x = (g1 * scale)[None] * d      # (steps, o, j)
            slow = g0 - np.where(self.direct, 0.0, m.fast)     # (direct: out of D)
            for o, j in np.ndindex(s.shape):
                shares = carried(float(decay[o, j]), float(s[o, j]), x[:, o, j],
                                 len(h) * s.size)
                out[part, o] += shares[:-1] + slow[o, j] * scale * d[:, o, j]
                s[o, j] = shares[-1]
        return out, s

    def _split(self, d_part: np.ndarray) -> np.ndarray:
        """The direct part D (outputs, inputs), and where some is lazy, its other parts then
        its lazy parts side by side (outputs, 2 inputs), as steps() lays out the misses."""
        if not self.lazy.any():
            return d_part
        return np.concatenate((np.where(self.lazy, 0.0, d_part),
                               np.where(self.lazy, d_part, 0.0)), axis=1)

    def _segments(self, h: np.ndarray, k: int, branch: int = 0) -> list[tuple[slice, int]]:
        """The steps k .. k + len(h) - 1 (with a `branch`, the last that many rows the steps
        before them again) in runs with one probe (the last made at or before each) and one
        step length: (rows, the probe's index in `found`)."""
        at = [f[0] for f in self.found]
        ks = with_branch(k + np.arange(len(h) - branch), branch)
        which = np.maximum(np.searchsorted(at, ks, side="right") - 1, 0)
        return _segments(which, h)

    def _forget(self) -> None:
        """Drop the probes no later step uses (all but the last at or before step k): memory
        flat on a long run. The list is replaced, not cut in place (a copy of the model, the
        Jacobi tail's, keeps its own)."""
        at = [f[0] for f in self.found]
        first = max(int(np.searchsorted(at, self.k, side="right")) - 1, 0)
        if first:
            self.found = self.found[first:]

    def linear(self, h: np.ndarray, held: np.ndarray, error: np.ndarray, change: np.ndarray,
               branch: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The steps in the form a loop carries (pair_loop.py; PoseBatch.linear's): E_k+1 =
        A_k E_k + made_k + B_k (the held inputs' further error), E the outputs' error. Only
        a response of first order has it (g1 = r g0, one r per output for every input):
        then A = r, B = g0, made = g0 (error - m change); with two poles, E = H X, X their
        shares (_modal_linear: H the fourth term); else the model is marked failed (the pair
        hands over) and the terms are zeros. With a `branch`, as steps()."""
        n, o, i = len(h), len(self.outputs), len(self.inputs)
        a, b, made = np.zeros((n, o, o)), np.zeros((n, o, i)), np.zeros((n, o))
        if not self.found:
            self.k += n - branch
            return a, b, made
        if len(self.found[0]) > 7:      # two poles: their shares, and the outputs' map
            return self._modal_linear(h, error, change, branch)
        for part, probe in self._segments(h, self.k, branch):
            _, size, g0, g1, r, m, d_part, *modes = self.found[probe]
            rate = first_order(g0, g1, r) if not (d_part.any() or modes or m.fast[
                self.direct].any()) else None     # (a direct fast part: direct_fast's)
            if rate is None:
                self.failed = (f"{self.name}'s measured response is not of first order in "
                               "every input, or an input reaches an output directly, and the "
                               "pair carries an error around a loop only through a state")
                break
            scale = float(h[part.start]) / size
            a[part] = np.diag(np.where(rate > 0, np.abs(rate) ** scale, rate))
            b[part] = g0 * scale
            made[part] = sum(np.einsum("oj,koj->ko", part_g0 * scale, error[part][:, None, :]
                                       - mi[None] * change[part][:, None, :])
                             for part_g0, mi in ((g0 - m.fast, m.carried), (m.fast, m.quick)))
        self.k += n - branch
        self._forget()
        return a, b, made

    def _modal_linear(self, h: np.ndarray, error: np.ndarray, change: np.ndarray,
                      branch: int) -> tuple:
        """linear()'s with two poles (probe_fit.modal_linear): X the modes' shares, E = H X;
        (A, B, made, H). A direct part marks the model failed, as for one pole."""
        shape = self.found[0][7][0].shape
        size = 2 * int(np.prod(shape))
        a, b = np.zeros((len(h), size, size)), np.zeros((len(h), size, len(self.inputs)))
        made = np.zeros((len(h), size))
        for part, probe in self._segments(h, self.k, branch):
            found = self.found[probe]
            if found[6].any() or found[5].fast.any():
                self.failed = (f"{self.name}'s measured response reaches an output directly "
                               "or has a part gone within the step, and the pair carries an "
                               "error around a loop only through a state")
                break
            a[part], b[part], made[part] = modal_linear(found[7], float(h[part.start]) /
                                                        found[1], error[part], change[part])
        self.k += len(h) - branch
        self._forget()
        return a, b, made, modal_outputs(shape)


def _weighed(error: np.ndarray, change: np.ndarray, bent: np.ndarray, m: np.ndarray,
             b: np.ndarray) -> np.ndarray:
    """(steps, outputs, inputs): the held value against the input's mean weighed as a pole of
    moment m and bend b weighs it: error - m change - 6 b bent (probe_fit.bend)."""
    return error[:, None, :] - m[None] * change[:, None, :] - (6 * b)[None] * bent[:, None, :]


def _modal(modes: tuple, scale: float, shape: tuple, out: np.ndarray, s: np.ndarray,
           work: int) -> np.ndarray:
    """ProbedModel._run's steps of a probe with two poles (probe_fit, `modes`: z, c, m, b,
    each (2, outputs, inputs)): per mode, d = error - m change - 6 b bent (`shape`: error,
    change, bent), its past share carried on by z^scale with c d added, its within-step
    response c / z d; their real parts added into `out` (steps, outputs). `s`: the modes'
    past shares (2, outputs, inputs), complex (zeros where the model has had one pole so
    far). Returns the shares after the last step."""
    z, c, m, b = modes
    error, change, bent = shape
    s = s.astype(complex) if s.shape == z.shape else np.zeros_like(z)
    within = within_step(z, c) * scale
    for i, o, j in np.ndindex(z.shape):
        if c[i, o, j] == 0:
            continue
        d = error[:, j] - m[i, o, j] * change[:, j] - 6 * b[i, o, j] * bent[:, j]
        shares = carried(complex(z[i, o, j]) ** scale, complex(s[i, o, j]),
                         c[i, o, j] * scale * d, work)
        out[:, o] += (shares[:-1] + within[i, o, j] * d).real
        s[i, o, j] = shares[-1]
    return s


def _segments(which: np.ndarray, h: np.ndarray) -> list[tuple[slice, int]]:
    """The runs of steps with one probe and one step length (the last step may be shorter)."""
    cuts = np.flatnonzero((np.diff(which) != 0) | (np.diff(h) != 0)) + 1
    bounds = [0, *cuts.tolist(), len(h)]
    return [(slice(a, b), int(which[a])) for a, b in zip(bounds, bounds[1:])]
