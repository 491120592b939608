"""The probes before the run steps: which third-party FMUs hold a state, where their model
descriptions do not say (docs/masters.md, "An FMU that declares no dependencies").

An output whose dependencies are not declared may depend on every input and on a state (FMI);
pythonfmu and pythonfmu3 declare none. From each such FMU's state at t0 (after
initialisation), it is stepped twice with its linked inputs as they are, then again with each
input moved by a small eps over the first step only; its state is set back after each
(probe.Target, 2 (1 + inputs) doStep calls). An FMU whose outputs keep no trace of the move
after the second step holds no state the coupling can see: the pair takes it as an FMU
without a state (pair.pair_plan's `memoryless`), and its later probes check it again.

An FMU whose every output declares inputs only is taken to hold no state (plan.has_state),
which FMI 2.0 does not promise of a co-simulation FMU (a PI controller, u = kp e + i, declares
u: [r, y]). The same probe checks it (declared_free): a trace of the move refutes the pair,
which would read its outputs as exact, and the adaptive master holds its inputs as a state's
(hidden_at_start).

A scenario's `dependencies:` (scenario/dependencies.py) that says an output depends on no
input (a state's) is the user's word, and the step order rests on it. The same probe checks
it: an output that the move changes within the first step and that keeps no trace after the
second is made from the inputs, not from a state; the pair does not apply, and says why.

After the run, an FMU with a state whose outputs all declare nothing gets advice: its inputs
were held at their end values, as a direct input's must be (first order on a lag); its probes
(probed_model.ProbedModel) measured which linked inputs each output reads directly (its direct
part), and said in the scenario (`dependencies: {x: [], y: [u]}`) they are held at their
step mean while it steps (plan.holds_through; second order). Where an output that reads an
input is worked out in doStep alone (probe.lazy: it does not follow the input set after the
step), none is advised: it reads the value held during the step, the mean once declared, and
only an output worked out when it is read gains.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plan import has_state, state_only_inputs, state_undeclared
from .probe import ProbedResponse, Target, probed_response
from .probe_fit import PROBE_STEPS, SUBSTEPS
from .probed_model import REAL, ProbedModel, probeable, probed_model

NO_DIRECT = 1e-6    # a direct part under this share of the state's part is round-off


@dataclass(frozen=True)
class AtStart:
    """What the probes before the run found."""
    memoryless: frozenset = frozenset()     # the FMUs the pair takes as without a state
    calls: int = 0                          # their doStep calls
    refuted: str | None = None              # a scenario's `dependencies:` they contradict


def undeclared(graph) -> frozenset[str]:
    """The third-party FMUs that may hold a state only because their outputs' dependencies
    are not declared (plan.state_undeclared), and can be probed."""
    return frozenset(i.name for i in graph.instances
                     if i.name in graph.measured and state_undeclared(i) and probeable(i))


def declared_free(graph) -> frozenset[str]:
    """The third-party FMUs taken to hold no state because every output declares inputs only
    (plan.has_state), and can be probed: FMI 2.0 does not make a co-simulation FMU's output
    free of a state it does not declare (a PI controller, u = kp e + i, declares u: [r, y]),
    so the probe checks them; one that holds a state refutes the pair, which would read its
    outputs as exact."""
    return frozenset(i.name for i in graph.instances
                     if i.name in graph.measured and not has_state(i) and probeable(i))


def _claimed(graph) -> dict[str, list[str]]:
    """Per third-party FMU that can be probed, the outputs its component's `dependencies:`
    says depend on no input."""
    said = {c.name: [o for o, inputs in c.dependencies if not inputs]
            for c in graph.scenario.components}
    return {i.name: said[i.name] for i in graph.instances
            if said.get(i.name) and i.name in graph.measured and probeable(i)}


def probe_at_start(graph, running: list, real_slots: dict, real: np.ndarray, t0: float,
                   h: float) -> AtStart:
    """Probe the FMUs of undeclared(), _claimed() and declared_free() at t0, with step h.
    Raises stepping.StepFailure (a probe's call returned Error or worse). Every one of them is
    a third-party FMU (Graph.measured): a graph without one has none to probe."""
    if not graph.measured:
        return AtStart()
    by_name, maybe, claims = {r.name: r for r in running}, undeclared(graph), _claimed(graph)
    free = declared_free(graph)
    found, calls, refuted = set(), 0, None
    for inst in graph.instances:
        if inst.name not in maybe and inst.name not in claims and inst.name not in free:
            continue
        response = _response_at_start(graph, inst, by_name, real_slots, (t0, h, real))
        if response is None:
            continue
        calls += response.steps * (1 + len(response.inputs))
        if inst.name in maybe and response.failed is None:
            found.add(inst.name)
        if inst.name in free and response.trace.any():
            refuted = refuted or response.failed
        refuted = refuted or _refuted(response, claims.get(inst.name, ()), t0)
    return AtStart(frozenset(found), calls, refuted)


def hidden_at_start(graph, running: list, real_slots: dict, real: np.ndarray, t0: float,
                    h: float) -> frozenset[str]:
    """The FMUs of declared_free() whose probe from t0 (step h; 2 (1 + inputs) doStep calls)
    finds a state: an output keeps a trace of an input's move a step later. Raises
    stepping.StepFailure."""
    by_name, free = {r.name: r for r in running}, declared_free(graph)
    responses = (_response_at_start(graph, inst, by_name, real_slots, (t0, h, real))
                 for inst in graph.instances if inst.name in free)
    return frozenset(r.name for r in responses if r is not None and r.trace.any())


def _response_at_start(graph, inst, by_name: dict, real_slots: dict, at: tuple
                       ) -> ProbedResponse | None:
    """`inst`'s ProbedResponse on its linked Real inputs, probed now (`at`: t0, h, the run's
    Real buffer; stepped twice, probed_response's steps: a state keeps a trace), or None
    where it has none linked. Raises StepFailure."""
    links = _linked_reals(graph, inst, real_slots)
    if not links:
        return None
    response = probed_response([l.target.ref.variable for l in links], inst)
    _probe_now(by_name[inst.name], response, links, real_slots, at, response.steps)
    if response.failed is None and response.steps > 1 and inst.can_vary_step:
        _faster_trace(response, by_name[inst.name], inst, links, real_slots, at)
    return response


def _faster_trace(response: ProbedResponse, running, inst, links: list, real_slots: dict,
                  at: tuple) -> None:
    """The same probe over steps of h / SUBSTEPS: a state whose trace is gone within one
    step (x' = -100 x + u at 0.2 s: e^-20 of the move is left, below round-off) keeps one
    over a substep. Where it does, `response` is marked failed as a trace one step on
    marks it (the FMU holds a state): read as exact, a lag whose dependencies are not
    declared read "below round-off" for an error of 1e-4. (Made where the FMU can step
    shorter: Instance.can_vary_step.)"""
    t0, h, real = at
    fine = probed_response(response.inputs, inst)
    _probe_now(running, fine, links, real_slots, (t0, h / SUBSTEPS, real), fine.steps)
    if fine.trace.any():
        response.trace, response.failed = fine.trace, fine.failed.replace(
            "one step later", f"1/{SUBSTEPS} of a step later (a state faster than the step)")


def hidden_advice(names) -> list[str]:
    """The adaptive master's words for the FMUs hidden_at_start found."""
    return [f"'{name}' holds a state that its outputs' dependencies, on inputs only, do not "
            "say (FMI 2.0 does not ask a co-simulation FMU to; its probe found it), so the "
            "adaptive master held its inputs as a state's: their step mean while it steps, "
            "their end value after" for name in names]


def lazy_at_start(graph, running: list, real_slots: dict, real: np.ndarray, t0: float,
                  h: float, room: int = 0) -> dict[str, list[str]]:
    """Per third-party FMU with a state whose inputs an output may read directly (the
    adaptive master holds them "through": their step mean while it steps, their end value
    for the outputs after it), its outputs, recorded or read by another FMU, that are worked
    out in its doStep alone (probe.lazy: they read the input within the step and do not
    follow it set after the step), where there are some. Probed from t0 with step h
    (ProbedModel's probe: 4 (1 + inputs) doStep calls; again over 6 where one pole does not
    fit and `room`, the steps of h the run spans after t0, has them). Raises
    stepping.StepFailure."""
    by_name, found, used = {r.name: r for r in running}, {}, used_outputs(graph)
    position = {inst.name: i for i, inst in enumerate(graph.instances)}
    for inst in graph.instances:
        if inst.name not in graph.measured or not has_state(inst) or not probeable(inst):
            continue
        own = state_only_inputs(inst)
        # (an input whose source steps later, a loop's, is not held "through")
        links = [l for l in _linked_reals(graph, inst, real_slots) if l.target.ref.variable
                 not in own and position[l.source.ref.instance] < position[inst.name]]
        model = probed_model(inst, [l.target.ref.variable for l in links]) if links else None
        if model is None:
            continue
        _probe_now(by_name[inst.name], model, links, real_slots, (t0, h, real), room=room)
        lazy = [o for o, row in zip(model.outputs, model.lazy)
                if row.any() and f"{inst.name}.{o}" in used]
        if model.failed is None and lazy:
            found[inst.name] = lazy
    return found


def _linked_reals(graph, inst, real_slots: dict) -> list:
    """The links into `inst`'s Real inputs from Real outputs (buffer slots in real_slots)."""
    return [l for l in graph.links if l.target.ref.instance == inst.name
            and l.target.type in REAL and l.source in real_slots]


def _probe_now(running, model, links: list, real_slots: dict, at: tuple,
               steps: int = PROBE_STEPS, room: int = 0) -> None:
    """One probe of `model` (ProbedModel, ProbedResponse) on the FMU's state now, its held
    inputs those of `links`; `at`: (t0, h, the run's Real buffer); `room`: Target.probe's.
    Raises StepFailure."""
    t0, h, real = at
    Target(running, model, model.inputs, model.outputs,
           np.array([real_slots[l.source] for l in links], dtype=np.intp), steps
           ).probe(0, t0, h, real, room)


def used_outputs(graph) -> set[str]:
    """The outputs ("instance.variable") the run records or another FMU reads: those whose
    values matter (an output worked out in doStep alone that none uses changes nothing)."""
    return {str(p.ref) for p in graph.recorded} | {str(l.source.ref) for l in graph.links}


def held_at_end_advice(found: dict[str, list[str]]) -> list[str]:
    """The adaptive master's words for the FMUs whose inputs it held at their end values
    (lazy_at_start found outputs worked out in their doStep alone)."""
    return [f"'{name}' works out its {', '.join(outputs)} in its doStep alone (an input set "
            "after the step does not move it, as FMI 2.0 asks of an output that reads an "
            "input directly), so the adaptive master held its inputs at their end values: "
            "first order, more steps; worked out when read (pythonfmu: a `getter=`), they "
            "would be held at their step mean while it steps (second order)"
            for name, outputs in found.items()]


def _refuted(response: ProbedResponse, claimed: list[str], t0: float) -> str | None:
    """Why the probe contradicts the scenario's word that these outputs depend on no input
    (moved within the step, no trace after the next), or None."""
    for name in claimed:
        i = response.outputs.index(name) if name in response.outputs else None
        if i is not None and response.moved[i] and not response.trace[i]:
            return (f"{response.name}.{name}: the scenario's dependencies: says it depends on "
                    f"no input, but probed at t = {t0:g} s it moves with {response.name}'s "
                    "inputs within the step and keeps no trace of them a step later (it is "
                    "made from them, not from a state): the step order breaks the loop where "
                    "no state holds it; give the dependencies: to the output of the FMU that "
                    "holds the state instead")
    return None


def advice(plan, used: set[str]) -> list[str]:
    """What to say in the scenario (module doc) for the FMUs of the pair's plan, under a
    master that blends a state's inputs (trapezoidal, quadratic); `used`: used_outputs (an
    output worked out in doStep alone that none uses stands in the way of nothing)."""
    if plan.hold not in ("trapezoidal", "quadratic"):
        return []
    said = []
    for g in plan.groups:
        m = g.model
        if not isinstance(m, ProbedModel) or not m.undeclared or m.failed or not m.found:
            continue
        _, _, g0, g1, _, moments, direct = m.found[-1][:7]
        if not (g1 != 0).any():
            continue
        direct = direct + np.where(m.lazy, moments.fast, 0.0)   # (probe_fit.direct_fast's)
        reads = np.abs(direct) > NO_DIRECT * np.abs(g0)     # (outputs, inputs)
        deps = ", ".join(f"{o}: [{', '.join(i for i, r in zip(m.inputs, row) if r)}]"
                         for o, row in zip(m.outputs, reads))
        lazy = [o for o, row in zip(m.outputs, m.lazy & reads)
                if row.any() and f"{m.name}.{o}" in used]
        said.append(_lazy_words(m.name, lazy, deps) if lazy else (
            f"'{m.name}' declares no output dependencies, so the {plan.hold} master held its "
            "inputs at their end values, as inputs its outputs may read must be (first "
            "order); its probes measured which of its linked inputs each output reads "
            f"directly: say so in the scenario, `{m.name}: {{fmu: ..., dependencies: "
            f"{{{deps}}}}}`, and its inputs are held at their mean over the step while it "
            "steps (second order)"))
    return said


def _lazy_words(name: str, lazy: list[str], deps: str) -> str:
    """The advice for an FMU some of whose outputs read an input directly but are worked out
    in its doStep alone (probe.lazy): such an output reads the value the input was held at
    during the step, so no hold makes both it and the state second order."""
    return (f"'{name}' declares no output dependencies, and its {', '.join(lazy)} "
            f"{'is' if len(lazy) == 1 else 'are'} worked out in its doStep alone (an input set "
            "after the step does not move it, as FMI 2.0 asks of an output that reads an "
            "input directly): no `dependencies:` makes both it and the state second order, "
            "and none is advised; worked out when read (pythonfmu: a `getter=`), it would "
            f"take `{name}: {{fmu: ..., dependencies: {{{deps}}}}}`, and its inputs would be "
            "held at their mean over the step while it steps (second order)")
