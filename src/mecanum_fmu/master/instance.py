"""One running FMU instance: the fmpy object, its raw C functions and its status rules.

FMI 2.0 and 3.0 alike (the version is the model description's): an FMI 3.0 FMU is reached
through master/fmi3.py, so that the stepping code calls the same attributes for both."""
from __future__ import annotations

import ctypes
import os

from fmpy.fmi2 import FMU2Slave

from ..errors import Problem, ScenarioError
from ..scenario.graph import Instance, Port
from ..runtime import RUNTIME, STATUS, Kept, own_slave_module
from . import fmi3

_fmi2Terminated = 3    # fmi2StatusKind
_fmi2LastSuccessfulTime = 2


class FmuCallError(Exception):
    """An FMI call returned Discard or worse: which call, on which instance, with what status."""

    def __init__(self, running: "RunningInstance", function: str, status: int):
        self.running, self.function, self.status = running, function, status
        super().__init__(f"{function} returned {STATUS.get(status, status)}")


def load_error(inst: Instance, what: str, err: BaseException, folder: str = "") -> ScenarioError:
    """The FMU of inst cannot be used: bad input (exit 2), naming the FMU and the component."""
    reason = str(getattr(err, "strerror", None) or err)
    if folder:      # name the member, not our temporary folder
        reason = reason.replace(folder.rstrip("/") + "/", "")
    reason = " ".join(reason.split())[:300]
    fix = {"cannot be loaded": "export it again for this platform",
           "cannot be extracted": "the archive is damaged or unsafe; export the FMU again"
           }.get(what, "export the FMU again")
    return ScenarioError([Problem(str(inst.fmu_path), inst.declared_at,
                                  f"the FMU of component '{inst.name}' {what}: {reason}; {fix}")])


_NAMES2 = {"reset": "fmi2Reset", "free": "fmi2FreeInstance", "terminate": "fmi2Terminate",
           "get_state": "fmi2GetFMUstate", "set_state": "fmi2SetFMUstate",
           "free_state": "fmi2FreeFMUstate"}
_NAMES3 = {"reset": "fmi3Reset", "free": "fmi3FreeInstance", "terminate": "fmi3Terminate",
           "get_state": "fmi3GetFMUState", "set_state": "fmi3SetFMUState",
           "free_state": "fmi3FreeFMUState"}


class RunningInstance:
    """An instance taken from the runtime's pool (reset) or instantiated afresh, and handed
    back (or freed) by free(). Transfers are filled in by the plan."""

    def __init__(self, inst: Instance):
        self.inst = inst
        self.name = inst.name
        md = inst.model
        try:
            unzipped = RUNTIME.extracted(inst.fmu_path)
        except (ValueError, OSError) as err:   # archive.ArchiveError is a ValueError
            raise load_error(inst, "cannot be extracted", err) from None
        self.key = (unzipped, md.guid, inst.name)
        kept = RUNTIME.take(self.key)
        if kept is None:
            cwd = os.getcwd()      # fmpy changes into the binary's folder to load it and
            try:                   # does not change back when the load fails
                slave = fmi3.Fmu3 if md.fmiVersion.startswith("3.") else FMU2Slave
                self.fmu = slave(guid=md.guid, unzipDirectory=unzipped,
                                     modelIdentifier=md.coSimulation.modelIdentifier,
                                     instanceName=inst.name)
            except Exception as err:     # no or a broken binary, missing FMI functions
                os.chdir(cwd)
                raise load_error(inst, "cannot be loaded", err, unzipped) from None
            self.component, self.log = None, RUNTIME.new_log()
        else:
            self.fmu, self.component, self.log = kept.fmu, kept.component, kept.log
        f = self.fmu._functions
        self.fmi3 = isinstance(self.fmu, fmi3.Fmu3)
        self.names = _NAMES3 if self.fmi3 else _NAMES2    # the FMI functions, by what they do
        if self.fmi3:
            self.fmu.enums = frozenset(v.valueReference for v in md.modelVariables
                                       if v.type == "Enumeration")
            self.c_get, self.c_set, self.c_do_step = fmi3.raw_calls(f, self.fmu.enums)
        else:
            self.c_get = {"Real": f["fmi2GetReal"], "Integer": f["fmi2GetInteger"],
                          "Boolean": f["fmi2GetBoolean"]}
            self.c_set = {"Real": f["fmi2SetReal"], "Integer": f["fmi2SetInteger"],
                          "Boolean": f["fmi2SetBoolean"]}
            self.c_do_step = f["fmi2DoStep"]
        # fmi2GetFMUstate/SetFMUstate/FreeFMUstate: the quadratic master's rollback
        self.c_get_state, self.c_set_state, self.c_free_state = (
            f.get(self.names["get_state"]), f.get(self.names["set_state"]),
            f.get(self.names["free_state"]))
        self.state = ctypes.c_void_p()
        self.state_ref = ctypes.byref(self.state)
        self.broken = 0       # worst status returned: Error (3) or Fatal (4) limit what may follow
        self.failed = False   # returned Discard or worse: freed, never kept
        self.reads: list = []     # (c_get, vrs, n, pointer), filled by the plan
        self.writes: list = []    # (fill, c_set, vrs, n, pointer)
        self.resets: list = []    # the same, set after doStep and before the reads (plan.py)
        self.settles: list = []   # the writes of a settle (stepping.settle): the newest values

    def function_name(self, name: str) -> str:
        """This instance's name for an FMI 2.0 function the stepping code names in a failure
        (fmi2SetFMUstate is fmi3SetFMUState for an FMI 3.0 FMU)."""
        if self.fmi3:
            return dict(zip(_NAMES2.values(), _NAMES3.values())).get(name, name)
        return name

    @property
    def can_roll_back(self) -> bool:
        """It says it can get and set its state, and has the functions to."""
        return self.inst.can_get_set_state and None not in (
            self.c_get_state, self.c_set_state, self.c_free_state)

    def call(self, function: str, status: int) -> None:
        if status > 1:
            raise FmuCallError(self, function, status)

    def mark_failed(self, status: int) -> None:
        self.broken = status if status >= 3 else 0
        self.failed = True

    def instantiate(self) -> None:
        if self.component is not None:           # kept: back to just instantiated
            status = self.fmu._functions[self.names["reset"]](self.component)
            if status <= 1:
                return
            if status < 4:
                self.fmu._functions[self.names["free"]](self.component)
            self.component = None
        # loggingOn: pythonfmu drops every message otherwise, errors included; the log keeps
        # the last few so that a failure can quote the FMU's own reason.
        own_slave_module(self.key[0])
        try:
            self.fmu.instantiate(callbacks=self.log.callbacks, loggingOn=True)
        except Exception as err:     # fmi2Instantiate returned NULL: a broken FMU
            why = self.log.last() or str(err)
            raise load_error(self.inst, "cannot be instantiated", Exception(why),
                             self.key[0]) from None
        self.component = self.fmu.component

    def terminate(self) -> None:
        # FMI 2.0: after Error an instance may only be freed; after Fatal, not even that.
        if self.component is not None and not self.broken:
            self.fmu._functions[self.names["terminate"]](self.component)

    def free(self) -> None:
        """Back to the pool if it ended cleanly, else fmi2FreeInstance only: the library is
        never unloaded. An instance that returned Fatal is left alone (pythonfmu crashes the
        process if it is touched again)."""
        if self.component is None:
            return
        if not self.failed and RUNTIME.keep(self.key, Kept(self.fmu, self.component, self.log)):
            pass
        elif self.broken < 4:
            self.fmu._functions[self.names["free"]](self.component)
            RUNTIME.forget_log(self.log)
        self.component = None

    def step_failure(self) -> str:
        """Name the failed step; 'terminated early' only when the FMU itself says so."""
        name = "fmi3DoStep" if self.fmi3 else "fmi2DoStep"
        return name + (" (the FMU terminated early)" if self.ends_run() else "")

    def ends_run(self) -> bool:
        """Whether its last doStep asked to end the simulation: fmi2Discard with
        fmi2GetBooleanStatus(fmi2Terminated) true, or fmi3DoStep's terminateSimulation."""
        if self.fmi3:
            return bool(self.c_do_step.terminated())
        return self._status("fmi2GetBooleanStatus", _fmi2Terminated, ctypes.c_int(0)) == 1

    def reached(self, end: float, h: float) -> bool:
        """Whether its last doStep, one that asked to end the simulation, got to `end` (its
        last successful time within 1e-6 of the step h): its outputs are then those at end."""
        last = self.c_do_step.last_time() if self.fmi3 else self._status(
            "fmi2GetRealStatus", _fmi2LastSuccessfulTime, ctypes.c_double(float("nan")))
        return last is not None and abs(last - end) <= 1e-6 * h

    def _status(self, function: str, kind: int, value):
        """fmi2GetXStatus(kind): its value, or None where the call fails or is missing."""
        try:
            status = self.fmu._functions[function](self.component, kind, ctypes.byref(value))
        except Exception:   # an FMU may not export it at all
            return None
        return value.value if status == 0 else None

    def get_one(self, port: Port):
        getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                  "Boolean": self.fmu.getBoolean}[port.type]
        return getter([port.vr])[0]

    def set_one(self, port: Port, value) -> None:
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                  "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}[port.type]
        setter([port.vr], [value])
