"""What the direct-feedthrough slaves share; inlined into each FMU script like the block maths
(the line that imports it ends in `# inline`)."""
from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Status

from mecanum_fmu.models.slaves.state import QuickState  # inline


class FeedthroughSlave(QuickState, Fmi2Slave):
    """A block whose outputs follow its inputs at once: recomputed on every set of an input and
    at initialization (after checking the parameters), so a master that sets the inputs reads
    consistent outputs without a step; a step has nothing left to do."""

    def _check(self):
        """Raise ValueError for a parameter outside its range (logged as the FMU's error)."""

    def _update(self):
        raise NotImplementedError

    def set_real(self, vrs, values):
        super().set_real(vrs, values)
        self._update()

    def enter_initialization_mode(self):
        try:
            self._check()
        except ValueError as err:
            self.log(f"{type(self).__name__}: {err}", Fmi2Status.error)
            raise
        self._update()

    def exit_initialization_mode(self):
        self.enter_initialization_mode()   # parameters may have changed during initialization

    def do_step(self, current_time, step_size):
        return True
