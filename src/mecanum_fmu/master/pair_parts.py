"""The embedded pair's plan, its parts (pair.py makes it): per FMU with a state its held inputs
(Group), the FMUs without a state an error is carried through (Through), a model's error around
a loop (Loop), FMUs with a state that feed one another (Node, Network), the whole (PairPlan)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Group:
    """One FMU's held Real inputs: their columns in the tapped rows, their roles ("state":
    blended by the trapezoidal and quadratic holds; "direct": the newest value; "through":
    held as "state", its end value set for the outputs (plan.holds_through); with
    "_ahead" or "fed_back": the same, closing a loop, their value of t_k+1 unknown when the
    FMU steps), the lag of their values (Jacobi: steps late), and the FMU's error model
    (None: it must see none)."""
    name: str
    cols: np.ndarray
    roles: np.ndarray
    lag: int
    model: object | None
    model_name: str = ""        # the FMU's model (its modelName), for the method's words
    lags: np.ndarray | None = None      # per input (in a Network they may differ); lag: the most

    @property
    def ahead(self) -> bool:
        """Whether an input closes a loop ("state_ahead", "fed_back"): its value of t_k+1 is
        extrapolated where the master does not roll back (pair_holds.RebuiltHolds._extrapolated)."""
        return any(r in ("state_ahead", "fed_back") for r in self.roles.tolist())


@dataclass
class PairPlan:
    slots: np.ndarray            # the buffer slots the tap keeps of every row
    groups: list[Group]
    lagged: list[tuple[str, int, int]]      # (output, column, lag): Jacobi's late outputs
    covered: dict[str, tuple[int, int]]     # output -> (group, index in its model's outputs)
    hold: str                    # "zoh", "trapezoidal", "quadratic" ; jacobi: "frozen"
    # the error models' outputs that other FMUs read: (output, group, index in its model's
    # outputs, column, the FMUs that read it); the pair holds where they carry no error
    fed: list = field(default_factory=list)
    rolled_back: bool = False    # the quadratic master predicts, rolls back, corrects a loop
    loop: "Loop | None" = None   # a model's error carried through FMUs without a state
    network: "Network | None" = None    # FMUs with a state that feed one another
    # the recorded outputs of the sensors (and of what reads them): name -> why unresolved
    unresolved: dict = field(default_factory=dict)
    # an error model's output read by FMUs with a model later in the step order (pair.
    # _forwarded): (its group, its index in the model's outputs, the reader's group, its
    # places among the reader's held inputs); its error is added to theirs
    forwarded: list = field(default_factory=list)
    # the graph holds FMUs the scenario layer knows nothing of (Graph.measured): values they
    # make may move on a grid of their own, which the pair checks (pair_rough.py); the
    # bundled blocks' are smooth between the breakpoints the graph carries, or sampled
    unknown: bool = False

    def throughs(self) -> list["Through"]:
        """The FMUs without a state an error is carried through: its loop's chain, or its
        network's FMUs between the models."""
        if self.loop is not None:
            return list(self.loop.chain)
        steps = self.network.steps if self.network is not None else ()
        return [item for kind, item in steps if kind == "through"]


@dataclass
class Through:
    """An FMU without a state that the pair carries an error through: its response (Graph.
    responses), the columns of its linked inputs' sources (in the response's order) and of
    its outputs, and (Jacobi) its lag behind the model's outputs."""
    name: str
    response: object
    ins: np.ndarray
    outs: np.ndarray
    lag: int = 0        # under Jacobi: its outputs' row r comes from its inputs' row r - 1


@dataclass
class Loop:
    """One error model's outputs carried through FMUs without a state (in step order), and
    back into its own held inputs where they close a loop: per row, the error of each
    carried value is its sensitivity to the model's outputs (the chain's Jacobians) times
    their error."""
    origin: int                     # the group whose model's outputs carry the error
    starts: list                    # (column, index in the model's outputs) of those read
    chain: list[Through]
    recorded: list                  # the chain's recorded outputs: (name, column)
    # carried values read by an FMU the pair cannot carry them through: (name, column, its
    # readers); the pair holds where they carry no error (as PairPlan.fed)
    checked: list
    # the chain's recorded outputs that divide by another output (Response.divides): (name,
    # the divisor's name, its column, the floor below which it does not divide); unresolved
    # where the divisor's error is not small against it
    divided: list = field(default_factory=list)


@dataclass
class Node:
    """One FMU with a state in a Network: its group; the place and size of its state's error
    in X (but its integrals') and of its integrals' in the network's integrals (the energies:
    states no rate depends on and no other FMU reads; their places in its model's state are
    `integral`, the others' `kept`); the columns of the outputs its model linearises about
    (None: its model's outputs are its state, as the pose's); per model output its column
    (None where the run keeps none)."""
    group: int
    offset: int
    size: int
    reads: np.ndarray | None
    outs: list
    kept: list = field(default_factory=list)
    integral: list = field(default_factory=list)
    first: int = 0          # its first integral's place among the network's


@dataclass
class Network:
    """The FMUs with an error model, where some feed one another (pair_network.py), and the
    FMUs without a state between them."""
    nodes: list[Node]
    steps: list             # in step order: ("node", Node) or ("through", Through)
    recorded: list          # the recorded outputs it covers: (name, column)
    checked: list           # its values read by FMUs outside it: (name, column, readers)
    size: int               # the size of X (every node's state but the integrals)
    integrals: list         # per integral: its output's name and column (None: not kept)
    made: dict = field(default_factory=dict)    # the values it makes -> their column
