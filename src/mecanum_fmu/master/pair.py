"""The fixed-step masters' error estimate from the run's own values: the embedded pair.

A fixed-step run's coupling error comes from what the master holds over a step: an FMU with a
state integrates the held value of an input that moves within the step, and under Jacobi
every FMU with direct feedthrough hands its value on a step late. The recorder's rows hold
every value that moves (plan.Buffers), so the pair takes no extra doStep. Per step and held
input:
- the master's own hold (the pair's lower-order member) is rebuilt from the values the input
  took: gauss-seidel's newest value, the trapezoid, the quadratic master's limited parabola,
  Jacobi's value of t_k;
- the higher-order member is the mean over the step of the cubic through the four nearest
  values of the same smooth piece of the sources (breakpoints.py: no piece reaches across a
  table's corner or a jump; a step that ends on a jump sees the left value, extrapolated,
  as the master steps it; a jump inside a step splits the step's mean between its pieces);
- held - that mean is the step's error of the input.
An FMU's error model (Graph.error_models' batch form: the PoseIntegrator's) carries those
errors into its outputs. The outputs of an FMU without a state (every output depends on an
input) read their inputs exactly: no error, or under Jacobi the lag d, row k against row
k + d. An FMU with a state and no error model must see no error at all (its inputs held
exactly: constants), else the estimate falls back to Richardson (richardson.py), as it does
where the pair cannot follow an error.

An FMU may read an error model's outputs (a loop closing back through a PoseIntegrator's
heading, any FMU downstream of one). Where the readers are FMUs without a state whose response
is known (Graph.responses: their Jacobians), the error is carried through them and around the
loop (Loop, pair_loop.py). Any other reader holds only where those outputs carry no error at
all (below their round-off), which the pair checks after the run, as it checks an FMU with a
state and no model: the error would have to go through that FMU's response. The input that
closes a loop into an FMU's state is held as the master holds it: its value of t_k
(Gauss-Seidel, Jacobi), extrapolated (the trapezoidal master, and the quadratic one where it
cannot roll back), or, where the quadratic master predicts, rolls back and corrects, the
limited parabola through the predicted end value. That is the run's own where the loop
carries no error, but for the steps whose predictor's extrapolation misses a corner (the
start, a kink, a jump): one step's error in the loop's predicted value, not carried on (the
corrector steps from the run's state); where the loop carries an error, pair_loop.py counts
the predicted values' own.

Where an error model is a linearisation (it has `linearised`: the drive train's motors and
floor, models/drive_error.py), the FMUs with an error model feed one another's errors: all of
them are solved together as a Network (pair_network.py), with the FMUs without a state between
them carrying the error by their responses, and each held input keeps a lag of its own under
Jacobi (a value the network makes carries its lag as an error instead).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..masters import entry as master_entry
from ..scenario.graph import Graph
from .pair_parts import Group, Loop, Network, Node, PairPlan, Through
from .plan import has_state, holds_through, state_only_inputs
from .probe import PROBED, probed_response
from .probed_model import ProbedModel, probed_model

METHOD = ("the embedded pair: per step, each held input's hold against the mean of the cubic "
          "through its nearest values in the same smooth piece ({steps}), carried "
          "into the outputs by their FMUs' error models ({models}){loop}; outputs of {other}"
          "FMUs without a state read their inputs exactly{lag}")
SAMPLED = ("unresolved ({models} sample at their own period, and this output is theirs or "
           "made from theirs: the pair does not follow a sample's error; --estimate "
           "richardson repeats the run at h/2)")
LOOP_METHOD = (", and through the Jacobians of {through}, whose outputs carry it (around a "
               "loop, back into the model's inputs)")


def pair_plan(graph: Graph, real_slots: dict, rolled_back: bool,
              memoryless: frozenset = frozenset()) -> PairPlan | str:
    """The pair's plan for this graph's fixed-step master, or why it has none: in step
    order, each FMU's outputs are exact (Jacobi: late by a lag), or an error model's, or
    (an FMU with a state and no model) exact if its held inputs do not move; an FMU that
    reads a model's outputs (or closes a loop) holds them exact if they carry no error.
    `real_slots`: the run's plan.Buffers.real_slots (where each Real output's value lives);
    `rolled_back`: the run predicts, rolls back and corrects each step (PairPlan.rolled_back);
    `memoryless`: the FMUs whose dependencies are not declared and that probes found without
    a state (memory.probe_at_start), taken as such.
    The sensors that sample at their own period, and what reads them, are left out (_opaque):
    their outputs are unresolved."""
    opaque = _opaque(graph)
    if isinstance(opaque, str):
        return opaque
    graph, unresolved = _without(graph, opaque)
    plan = _plan(graph, real_slots, rolled_back, memoryless)
    if isinstance(plan, PairPlan):
        plan.unresolved, plan.unknown = unresolved, bool(graph.measured)
    return plan


def _plan(graph: Graph, real_slots: dict, rolled_back: bool, memoryless: frozenset
          ) -> PairPlan | str:
    """pair_plan's, on a graph without the sensors."""
    how = master_entry(graph.scenario.experiment.master)
    stateful = lambda inst: has_state(inst) and inst.name not in memoryless   # noqa: E731
    position = {inst.name: i for i, inst in enumerate(graph.instances)}
    lag: dict[str, int] = {}        # the FMUs whose outputs are exact (Jacobi: late by lag)
    slots: dict[int, int] = {}
    groups: list[Group] = []
    models = dict(graph.error_models)
    modelled: dict[str, int] = {}   # the FMUs with an error model -> their group
    col = lambda port: slots.setdefault(real_slots[port], len(slots))   # noqa: E731
    into = {inst.name: [l for l in graph.links if l.target.ref.instance == inst.name]
            for inst in graph.instances}
    for inst in graph.instances:
        links = into[inst.name]
        loop = [l for l in links if position[l.source.ref.instance] >= position[inst.name]]
        if loop and not stateful(inst):
            return (f"{inst.name}'s input {loop[0].target.ref.variable} closes a feedback "
                    "loop through an FMU without a state, whose error the pair does not follow")
        if not links or not stateful(inst):
            d = _lag_in(inst, links, lag)
            if isinstance(d, str):
                return d
            lag[inst.name] = d + 1 if how.freezes_inputs and links else d
            continue
        group = _group(how, inst, links, set(map(id, loop)), col, models.get(inst.name),
                       inst.name in graph.measured)
        if isinstance(group, str):
            return group
        groups.append(group)
        lag[inst.name] = 0          # exact, or its model's (PairRows checks those fed on)
        if group.model is not None:
            modelled[inst.name] = len(groups) - 1
    fed = _fed(graph, groups, modelled, col)
    if isinstance(fed, str):
        return fed
    network = _network(graph, groups, col, real_slots, into)
    if isinstance(network, str):
        return network
    for g in groups:        # their inputs' lags, now that every source's is known
        lags = _lags_in(g, into[g.name], lag, network)
        if isinstance(lags, str):
            return lags
        g.lags, g.lag = lags, int(lags.max(initial=0))
    forwarded, fed = _forwarded(fed, groups, position) if network is None else ([], fed)
    loop = None if network else _loop(graph, groups, fed, col, real_slots, into, lag)
    plan = _outputs(graph, lag, groups, slots, col, "frozen" if how.freezes_inputs else how.hold)
    if isinstance(plan, PairPlan):
        plan.fed, plan.rolled_back, plan.loop, plan.network = fed, rolled_back, loop, network
        plan.forwarded = forwarded
        if loop is not None:        # its model's outputs are checked where the loop is
            plan.fed = [f for f in fed if f[1] != loop.origin]
        if network is not None:     # and every model's where the network is; the values
            plan.fed = []           # it makes carry their own lag under Jacobi
            plan.lagged = [l for l in plan.lagged if l[0] not in network.made]
    return plan


def _opaque(graph: Graph) -> set[str] | str:
    """The FMUs whose outputs the pair leaves unresolved: those that sample at their own
    period (Graph.sampled: the sensors) and have no error model, and every FMU that reads
    theirs (to a fixpoint: a loop may close through them); or why the pair cannot leave them
    out: an FMU with an error model is among them (the loop closes through the samples)."""
    if not graph.sampled:
        return set()
    models = dict(graph.error_models)
    opaque = {i.name for i in graph.instances
              if i.model_name in graph.sampled and i.name not in models}
    while True:
        readers = {l.target.ref.instance for l in graph.links
                   if l.source.ref.instance in opaque} - opaque
        if not readers:
            break
        opaque |= readers
    modelled = [i.name for i in graph.instances if i.name in opaque and i.name in models]
    if modelled:
        return (f"{modelled[0]} reads what {', '.join(graph.sampled)} sample at their own "
                "period (directly or through other FMUs), whose error the pair does not follow")
    return opaque


def _without(graph: Graph, opaque: set[str]) -> tuple[Graph, dict[str, str]]:
    """The graph without the FMUs in `opaque`, and their recorded Real outputs, unresolved."""
    if not opaque:
        return graph, {}
    kept = tuple(i for i in graph.instances if i.name not in opaque)
    links = tuple(l for l in graph.links if l.target.ref.instance not in opaque)
    recorded = tuple(p for p in graph.recorded if p.ref.instance not in opaque)
    models = sorted({i.model_name for i in graph.instances if i.name in opaque
                     and i.model_name in graph.sampled})
    text = SAMPLED.format(models=", ".join(models))
    return (dataclasses.replace(graph, instances=kept, links=links, recorded=recorded),
            {str(p.ref): text for p in graph.recorded
             if p.ref.instance in opaque and p.type == "Real"})


def _network(graph: Graph, groups: list[Group], col, real_slots: dict, into: dict
             ) -> "Network | str | None":
    """The Network of every FMU with an error model, where one of them is linearised (its
    model has `linearised`: the drive train's), else None; or why the pair cannot follow it.
    In step order, an FMU without a state that reads a value the network makes and has a
    response carries it on; any other reader is checked (Network.checked)."""
    if not any(hasattr(g.model, "linearised") for g in groups):
        return None
    probed = [g.name for g in groups if isinstance(g.model, ProbedModel)]
    if probed:
        return (f"{probed[0]}'s response is measured (it has a state and no error model), "
                "and the pair does not join a measured response to a linearised model's")
    ports = {str(p.ref): p for p in real_slots}
    nodes, made, offset, integrals = {}, {}, 0, []   # made: the values it makes -> column
    for i, g in enumerate(groups):
        if g.model is None:
            continue
        node = _node(g, i, col, ports, offset, integrals)
        if isinstance(node, str):
            return node
        nodes[g.name], offset = node, offset + node.size
        made.update({f"{g.name}.{o}": c for o, c in zip(g.model.outputs, node.outs)
                     if c is not None})
    read = {str(l.source.ref) for l in graph.links}
    fed = [name for name, _ in integrals if name in read]
    if fed:
        return f"{fed[0]} is an integral of its FMU's error model, which the pair does not feed on"
    throughs, checked = _carried_on(graph, into, made, set(nodes), {g.name for g in groups},
                                    col, ports, {})
    steps = [("node", nodes[i.name]) if i.name in nodes else ("through", throughs[i.name])
             for i in graph.instances if i.name in nodes or i.name in throughs]
    recorded = [(str(p.ref), made[str(p.ref)]) for p in graph.recorded if str(p.ref) in made]
    return Network(list(nodes.values()), steps, recorded,
                   [(name, made[name], sorted(r)) for name, r in checked.items()], offset,
                   integrals, made)


def _node(g: Group, i: int, col, ports: dict, offset: int, integrals: list) -> Node | str:
    """Group i's Node at `offset` in X, its integrals appended to `integrals` (name, column),
    or why the pair cannot linearise it (an output it reads is not kept)."""
    model, name = g.model, g.name
    column = lambda o: col(ports[f"{name}.{o}"]) if f"{name}.{o}" in ports else None  # noqa
    outs = [column(o) for o in model.outputs]
    if not hasattr(model, "linearised"):
        return Node(i, offset, len(outs), None, outs)
    missing = [r for r in model.reads if f"{name}.{r}" not in ports]
    if missing:
        return (f"{name}'s error model reads {name}.{missing[0]}, which the run does not keep "
                "(add it to outputs:)")
    integral = list(model.integrals.values())
    kept = [k for k in range(model.states) if k not in integral]
    node = Node(i, offset, len(kept), np.array([column(r) for r in model.reads]), outs, kept,
                integral, len(integrals))
    integrals.extend((f"{name}.{o}", column(o)) for o in model.integrals)
    return node


def _loop(graph: Graph, groups: list[Group], fed: list, col, real_slots: dict, into: dict,
          lag: dict) -> Loop | None:
    """The Loop of the one model whose outputs other FMUs read (None: no such model, or
    several, or no FMU to carry them through): in step order, each FMU without a state that
    reads a carried value and has a response covering its inputs carries it on; any other
    reader (but the model's own FMU, where the loop closes) is checked."""
    origins = {f[1] for f in fed}
    if len(origins) != 1:
        return None
    origin = origins.pop()
    carried = {name: c for name, _, _, c, _ in fed}
    starts = [(c, index) for _, _, index, c, _ in fed]
    ports = {str(p.ref): p for p in real_slots}
    throughs, checked = _carried_on(graph, into, carried, {groups[origin].name},
                                    {g.name for g in groups}, col, ports, lag)
    chain = list(throughs.values())
    if not chain:           # nothing to carry through: the model's outputs are checked (fed)
        return None
    members = {t.name for t in chain}
    recorded = [(str(p.ref), carried[str(p.ref)]) for p in graph.recorded
                if p.ref.instance in members and str(p.ref) in carried]
    divided = [(name, f"{t.name}.{d}", carried[f"{t.name}.{d}"], floor) for t in chain
               for out, (d, floor) in t.response.divides.items()
               if (name := f"{t.name}.{out}") in dict(recorded)]
    return Loop(origin, starts, chain, recorded,
                [(name, carried[name], sorted(readers)) for name, readers in checked.items()],
                divided)


def _carried_on(graph: Graph, into: dict, carried: dict, skip: set, stateful: set, col,
                ports: dict, lag: dict) -> tuple[dict, dict]:
    """In step order, each FMU but those in `skip` that reads a value in `carried` (its name
    -> its column): one without a state whose response covers its linked inputs carries it
    on (its Through, at its lag under Jacobi; its outputs join `carried`), any other reads
    it as it is, wherever it steps (one that steps before the value's FMU reads it around a
    loop: two lags in a row closed through a controller into the first). (FMU name -> its
    Through, in step order; value -> the FMUs that read it as it is, to be checked)."""
    responses = dict(graph.responses)
    throughs = {}
    for inst in graph.instances:
        links = [l for l in into[inst.name] if l.target.type == "Real"]
        if inst.name in skip or not any(str(l.source.ref) in carried for l in links):
            continue
        factory = responses.get(inst.name, probed_response if inst.name in graph.measured
                                else None)
        through = None if inst.name in stateful or factory is None else \
            _through(inst, links, factory, col, ports, lag.get(inst.name, 0))
        if through is not None:
            throughs[inst.name] = through
            carried.update({f"{inst.name}.{n}": c for n, c in zip(through.response.outputs,
                                                                    through.outs)})
    checked: dict[str, set] = {}
    for inst in graph.instances:
        if inst.name not in skip and inst.name not in throughs:
            for l in into[inst.name]:
                if l.target.type == "Real" and str(l.source.ref) in carried:
                    checked.setdefault(str(l.source.ref), set()).add(inst.name)
    return throughs, checked


def _through(inst, links: list, factory, col, ports: dict, lag: int) -> Through | None:
    """The Through of an FMU without a state, or None: its response does not cover its
    linked inputs, or an output it reads has no slot (neither linked nor recorded)."""
    response = factory([l.target.ref.variable for l in links], inst)
    if response is None:
        return None
    outs = [ports.get(f"{inst.name}.{n}") for n in response.outputs]
    if any(p is None for p in outs):
        return None
    return Through(inst.name, response, np.array([col(l.source) for l in links]),
                   np.array([col(p) for p in outs]), lag)


def _lags_in(g: Group, links: list, lag: dict, network: "Network | None") -> np.ndarray | str:
    """The lag of each of an FMU with a state's held inputs (Group.lags): its source's, but
    0 for a value a Network makes (it carries that value's lag as an error of its own,
    pair_network.py); one lag for all but there (else why the pair cannot follow them)."""
    if network is None or g.model is None:
        d = _lag_in(g, links, lag)
        return d if isinstance(d, str) else np.full(len(g.cols), d, dtype=np.int64)
    return np.array([0 if str(l.source.ref) in network.made else lag[l.source.ref.instance]
                     for l in links], dtype=np.int64)          # in the order of g.cols


def _lag_in(fmu, links: list, lag: dict) -> int | str:
    """The lag of an FMU's inputs (0 but under Jacobi: an FMU with a state, whose inputs may
    close a loop, once its sources' are known), or why the pair cannot follow them."""
    lags = {lag[l.source.ref.instance] for l in links}
    if len(lags) > 1:
        return f"{fmu.name}'s inputs arrive with different lags under Jacobi"
    return lags.pop() if lags else 0


def _fed(graph: Graph, groups: list[Group], modelled: dict, col) -> list | str:
    """The error models' outputs that other FMUs read (PairPlan.fed), or why one cannot be
    checked (its model does not cover it)."""
    fed: dict[str, tuple] = {}      # output -> (group, index in its model, column, readers)
    for l in graph.links:
        owner = l.source.ref.instance
        if owner not in modelled:
            continue
        outputs = list(groups[modelled[owner]].model.outputs)
        if l.source.ref.variable not in outputs or l.source.type != "Real":
            return (f"{l.target.ref.instance} reads {l.source.ref}, which {owner}'s error "
                    "model does not cover")
        entry = fed.setdefault(str(l.source.ref), (modelled[owner], outputs.index(
            l.source.ref.variable), col(l.source), set()))
        entry[3].add(l.target.ref.instance)
    return [(name, i, index, c, sorted(readers))
            for name, (i, index, c, readers) in fed.items()]


def _forwarded(fed: list, groups: list[Group], position: dict) -> tuple[list, list]:
    """(PairPlan.forwarded, the rest of `fed`): the error models' outputs read only by FMUs
    with an error model later in the step order, their error forwarded into those FMUs' held
    inputs: (the source's group, its index in the model's outputs, the reader's group, the
    places of the value among the reader's held inputs)."""
    by_name = {g.name: j for j, g in enumerate(groups) if g.model is not None}
    forwarded, rest = [], []
    for entry in fed:
        _, i, index, c, readers = entry
        later = all(r in by_name and position[r] > position[groups[i].name] for r in readers)
        if not later:
            rest.append(entry)
            continue
        forwarded += [(i, index, by_name[r], np.flatnonzero(groups[by_name[r]].cols == c))
                      for r in readers]
    return forwarded, rest


def _group(how, inst, links: list, loop: set, col, model, measured: bool) -> Group | str:
    """The held inputs of an FMU with a state, with its error model's batch form (None
    where it does not take these inputs); without a model, its response measured where
    `measured` (the scenario layer knows nothing of it: probed_model.ProbedModel), else None;
    `loop`: the ids of the links that close a loop into it. Its lag is set once every
    source's is known (pair_plan)."""
    if any(l.target.type != "Real" for l in links):
        return f"{inst.name} has a state and an input that is not Real"
    names = [l.target.ref.variable for l in links]
    state_only = state_only_inputs(inst)
    through = how.hold != "zoh" and holds_through(inst, measured)
    roles = np.array([_role(how.hold != "zoh" and n in state_only, id(l) in loop, through)
                      for n, l in zip(names, links)])
    if model is not None:
        batch, words = model.batch(names, inst), inst.model_name
    else:
        batch = probed_model(inst, names) if measured else None
        words = inst.model_name + (PROBED if batch is not None else "")
    return Group(inst.name, np.array([col(l.source) for l in links]), roles, 0, batch, words)


def _role(blended: bool, ahead: bool, through: bool = False) -> str:
    """An input's role in the pair's rebuilt hold (Group.roles); `through`: a direct input
    whose source steps first is held as a state's, then set to its end value
    (plan.holds_through)."""
    if blended:
        return "state_ahead" if ahead else "state"
    return "fed_back" if ahead else "through" if through else "direct"


def _outputs(graph: Graph, lag: dict, groups: list[Group], slots: dict, col, hold: str
             ) -> PairPlan | str:
    """The plan's recorded outputs: late (Jacobi) or covered by a model (the others are
    exact)."""
    covered, lagged = {}, []
    by_name = {g.name: (i, g) for i, g in enumerate(groups) if g.model is not None}
    for port in graph.recorded:
        if port.type != "Real":
            continue
        owner = port.ref.instance
        if owner in by_name:
            i, g = by_name[owner]
            if port.ref.variable not in g.model.outputs:
                return (f"{port.ref} is an output of {owner} that its error model does not "
                        "cover")
            covered[str(port.ref)] = (i, list(g.model.outputs).index(port.ref.variable))
        elif lag.get(owner, 0) > 0:
            lagged.append((str(port.ref), col(port), lag[owner]))
    order = np.array(sorted(slots, key=slots.get), dtype=np.intp)
    return PairPlan(order, groups, lagged, covered, hold)
