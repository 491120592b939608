"""What every slave shares: fmi2GetFMUstate and fmi2SetFMUstate with the variables' getters and
setters listed once; inlined into each FMU script like the block maths (the line that imports
it ends in `# inline`). It imports nothing, so it serves pythonfmu and pythonfmu3 alike.

The quadratic master saves and restores every FMU's state on each step (its predictor's
rollback). pythonfmu builds the list of variables again on every call (a dict by name on each
restore: about 14 us for a DCMotor, 2 s of a 10 s run of the belief drive); the state here is
the same dict, made and applied the same way, from lists made on first use.
"""
_NO_VARIABLE = object()


class QuickState:
    """Put before the pythonfmu base: `class Model(QuickState, Fmi2Slave)`."""

    def _get_fmu_state(self):
        """{variable name: value} of every variable, as pythonfmu's own."""
        getters = self.__dict__.get("_state_getters")
        if getters is None or len(getters) != len(self.vars):
            getters = self._state_getters = [(v.name, v.getter) for v in self.vars.values()]
        return {name: get() for name, get in getters}

    def _set_fmu_state(self, state):
        """Each value through its variable's setter (none for a constant or an output with no
        attribute of its name); a name that is no variable (a slave's own state) set as an
        attribute, as pythonfmu's own."""
        setters = self.__dict__.get("_state_setters")
        if setters is None or len(setters) != len(self.vars):
            setters = self._state_setters = {v.name: v.setter for v in self.vars.values()}
        for name, value in state.items():
            setter = setters.get(name, _NO_VARIABLE)
            if setter is _NO_VARIABLE:
                setattr(self, name, value)
            elif setter is not None:
                setter(value)
