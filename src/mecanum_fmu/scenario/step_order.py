"""The step order of a graph's instances (graph.Instance) and the walking order of its links
(graph.Link): from a variable-level dependency graph, a connection output -> input and,
inside an FMU, input -> output for each ModelStructure dependency (graphlib); a cycle in it is
an algebraic loop, refused; a loop closed into an FMU's state is broken there."""
from __future__ import annotations

import graphlib

from ..errors import Problem, ScenarioError
from .dependencies import loop_hint


def dependency_order(instances: list, links: list, label: str) -> tuple[list, list]:
    """Step order of the instances and walking order of the links, from a variable-level
    dependency graph: a connection output -> input, and inside an FMU input -> output for each
    ModelStructure dependency. A cycle in it is an algebraic loop; a cycle through an FMU
    whose outputs do not depend on its inputs (an integrator) is not one."""
    graph: dict[str, set[str]] = {}
    link_of: dict[str, object] = {}     # input -> its Link
    for link in links:
        graph.setdefault(str(link.target.ref), set()).add(str(link.source.ref))
        link_of[str(link.target.ref)] = link
    for inst in instances:
        inputs = [v for v in inst.model.modelVariables if v.causality == "input"]
        for unknown in inst.model.outputs:
            deps = unknown.dependencies
            if deps is None:      # not declared: FMI says it may depend on every input
                deps = inputs
            out = f"{inst.name}.{unknown.variable.name}"
            for dep in deps:
                if dep.causality == "input":
                    graph.setdefault(out, set()).add(f"{inst.name}.{dep.name}")
    sorter = graphlib.TopologicalSorter(graph)
    try:
        order = list(sorter.static_order())
    except graphlib.CycleError as err:
        cycle = err.args[1]
        places = sorted({link_of[n].place for n in cycle if n in link_of})
        raise ScenarioError([Problem(label, ", ".join(places) or "connections",
            "algebraic loop: " + " -> ".join(cycle) + " (every block on it has direct "
            "feedthrough; break it with a block whose outputs do not depend on its inputs)"
            + loop_hint(cycle, instances))]) from None
    position = {node: i for i, node in enumerate(order)}
    link_order = sorted(links, key=lambda l: position[str(l.target.ref)])
    # An instance steps after the latest of its connected inputs in the dependency order.
    last_input: dict[str, int] = {}
    feedback = _feedback_into_state(instances, links)
    for node, link in link_of.items():
        if node in feedback:
            continue
        name = link.target.ref.instance
        last_input[name] = max(last_input.get(name, -1), position[node])
    declared = {inst.name: i for i, inst in enumerate(instances)}
    key = {i.name: (last_input.get(i.name, -1), declared[i.name]) for i in instances}
    return _after_sources(instances, links, feedback, key), link_order


def _after_sources(instances: list, links: list, feedback: set[str], key: dict) -> list:
    """The instances sorted by key, except that each steps after the instances feeding it
    (outside the feedback into a state), so that it takes their t_k+1 values, also from a
    block whose outputs do not depend on its inputs (an Encoder feeding an Odometry). Where
    the key order already does so it is kept; an instance-level cycle keeps the key order."""
    by_key = sorted(instances, key=lambda i: key[i.name])
    sorter = graphlib.TopologicalSorter({i.name: set() for i in instances})
    for link in links:
        source, target = link.source.ref.instance, link.target.ref.instance
        if str(link.target.ref) not in feedback and source != target:
            sorter.add(target, source)
    try:
        sorter.prepare()
    except graphlib.CycleError:
        return by_key
    named, ready, order = {i.name: i for i in instances}, set(), []
    while sorter.is_active():
        ready.update(sorter.get_ready())
        first = min(ready, key=lambda n: key[n])
        ready.remove(first)
        order.append(named[first])
        sorter.done(first)
    return order


def _feedback_into_state(instances: list, links: list) -> set[str]:
    """Inputs (`instance.input`) that close a feedback loop into an FMU's state: no output of
    their FMU depends on them and their source is downstream of their FMU. Such an FMU steps
    before the rest of its loop (on extrapolated inputs), so that the blocks with direct
    feedthrough downstream see its outputs at the end of the step: a closed loop then keeps
    the master's order (docs/masters.md). Open chains have none: their order is as before."""
    downstream: dict[str, set[str]] = {}
    for link in links:
        downstream.setdefault(link.source.ref.instance, set()).add(link.target.ref.instance)

    def reaches(start: str, goal: str) -> bool:
        seen, todo = {start}, [start]
        while todo:
            for nxt in downstream.get(todo.pop(), ()):
                if nxt == goal:
                    return True
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return False

    depended: dict[str, set[str] | None] = {}
    for inst in instances:
        names: set[str] | None = set()
        for unknown in inst.model.outputs:
            if unknown.dependencies is None:
                names = None          # undeclared: may depend on every input
                break
            names |= {d.name for d in unknown.dependencies}
        depended[inst.name] = names
    out = set()
    for link in links:
        target, source = link.target.ref, link.source.ref.instance
        names = depended.get(target.instance)
        if names is not None and target.variable not in names and reaches(target.instance, source):
            out.add(str(target))
    return out
