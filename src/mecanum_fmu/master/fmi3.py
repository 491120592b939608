"""FMI 3.0 co-simulation FMUs under the FMI 2.0 calls the master makes.

RunningInstance (instance.py) takes fmpy's FMU3Slave as Fmu3 below and the raw calls from
raw_calls(), so the stepping code calls the same things for both versions: c_get[kind] and
c_set[kind] (fn(component, vrs, n, pointer)), c_do_step (fn(component, t, h, flag)), the state
functions, and the fmpy object's setupExperiment / enterInitializationMode / getReal / ...
The master's kinds map to FMI 3.0 types: Real is Float64, Integer is Int32, Boolean is
fmi3Boolean (one byte, copied to and from the master's int32 buffer).
"""
from __future__ import annotations

import ctypes

from fmpy.fmi3 import FMU3Slave, fmi3IntermediateUpdateCallback

from ..runtime import RUNTIME

DISCARD = 2     # fmi3Discard, fmi2Discard

_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


class Fmu3(FMU3Slave):
    """fmpy's FMI 3.0 slave with the FMI 2.0 names the master calls."""

    _experiment = (None, 0.0, None)

    def instantiate(self, callbacks=None, loggingOn=False, **_):
        """Instantiate with our logger: the instance's log key as its environment."""
        self.logMessage = RUNTIME.logger3
        resources = (self.unzipDirectory.rstrip("/") + "/resources/").encode()
        self.component = self.fmi3InstantiateCoSimulation(
            self.instanceName.encode(), self.guid.encode(), resources, False, loggingOn,
            False, False, None, 0, ctypes.c_void_p(callbacks.componentEnvironment),
            self.logMessage, fmi3IntermediateUpdateCallback())
        if not self.component:
            raise Exception("Failed to instantiate FMU")

    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None):
        self._experiment = (tolerance, startTime, stopTime)

    def enterInitializationMode(self):
        tolerance, start, stop = self._experiment
        super().enterInitializationMode(tolerance=tolerance, startTime=start, stopTime=stop)

    def getReal(self, vr):
        return self.getFloat64(vr)

    enums: frozenset = frozenset()      # its Enumeration references: Int64 in FMI 3.0

    def getInteger(self, vr):
        return [self.getInt64([v])[0] if v in self.enums else self.getInt32([v])[0]
                for v in vr] if self.enums else self.getInt32(vr)

    def setReal(self, vr, values):
        self.setFloat64(vr, values)

    def setInteger(self, vr, values):
        if not self.enums:
            self.setInt32(vr, values)
            return
        for v, value in zip(vr, values):
            (self.setInt64 if v in self.enums else self.setInt32)([v], [value])


def raw_calls(f: dict, enums: frozenset = frozenset()) -> tuple[dict, dict, object]:
    """(c_get, c_set, c_do_step) over fmpy's FMI 3.0 function table f; `enums`: the FMU's
    Enumeration references, which the master's Integer kind holds (int32, as FMI 2.0's) and
    FMI 3.0 gets and sets as Int64."""
    c_get = {kind: _scalars(f[f"fmi3Get{t}"]) for kind, t in _TYPES.items()}
    c_set = {kind: _scalars(f[f"fmi3Set{t}"]) for kind, t in _TYPES.items()}
    c_get["Boolean"], c_set["Boolean"] = _get_booleans(f["fmi3GetBoolean"]), _set_booleans(
        f["fmi3SetBoolean"])
    if enums:
        c_get["Integer"] = _with_enums(c_get["Integer"], f["fmi3GetInt64"], enums, True)
        c_set["Integer"] = _with_enums(c_set["Integer"], f["fmi3SetInt64"], enums, False)
    return c_get, c_set, _do_step(f["fmi3DoStep"])


def _with_enums(int32, int64, enums: frozenset, get: bool):
    """An Integer get or set (fn(component, vrs, n, pointer), the master's int32 values) that
    takes the Enumeration references through fmi3Get/SetInt64, the others through `int32`."""
    def call(component, vrs, n, pointer):
        status = 0
        for wide, function in ((False, int32), (True, int64)):
            at = [i for i in range(n) if (vrs[i] in enums) == wide]
            if not at:
                continue
            refs = (ctypes.c_uint * len(at))(*[vrs[i] for i in at])
            values = ((ctypes.c_int64 if wide else ctypes.c_int32) * len(at))(
                *([0] * len(at) if get else [pointer[i] for i in at]))
            status = max(status, function(component, refs, len(at), values, len(at)) if wide
                         else function(component, refs, len(at), values))
            if get:
                for j, i in enumerate(at):
                    pointer[i] = values[j]
        return status
    return call


def _scalars(function):
    """fmi3Get/SetX take the number of values too: for scalars, the number of references."""
    return lambda component, vrs, n, pointer: function(component, vrs, n, pointer, n)


def _get_booleans(function):
    def get(component, vrs, n, pointer):
        values = (ctypes.c_bool * n)()
        status = function(component, vrs, n, values, n)
        for i in range(n):
            pointer[i] = values[i]
        return status
    return get


def _set_booleans(function):
    def set_(component, vrs, n, pointer):
        return function(component, vrs, n, (ctypes.c_bool * n)(*pointer[:n]), n)
    return set_


def _do_step(function):
    """fmi3DoStep with its four out-arguments; the last call's terminate flag and last
    successful time are kept. A step that returns OK with terminateSimulation set returns
    Discard here, as FMI 2.0 says it: the stepping code sees a step that asks to end the
    run (RunningInstance.ends_run) where it sees every other refusal."""
    event, terminate, early, last = (ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(),
                                     ctypes.c_double())
    refs = (ctypes.byref(event), ctypes.byref(terminate), ctypes.byref(early),
            ctypes.byref(last))

    asked = [0.0]   # the end of the last step asked for

    def do_step(component, t, h, no_prior):
        asked[0] = t + h
        status = function(component, t, h, no_prior, *refs)
        return DISCARD if status < DISCARD and terminate.value else status
    do_step.terminated = lambda: terminate.value
    do_step.last_time = lambda: last.value if early.value else asked[0]
    return do_step
