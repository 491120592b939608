"""The slaves as FMI 3.0 FMUs: pythonfmu's names that a slave uses, provided over pythonfmu3.

`make fmus` builds every slave a second time, into fmus/fmi3/ (models/build3.py): this module
is inlined in place of the slave script's pythonfmu imports, so the same slave class and the
same block maths run under pythonfmu3; nothing of a model is written twice. What differs:
Real is Float64, Integer is Int32, pythonfmu3 calls set_float64 (routed to the slave's
set_real), and Fmi3Model adds the array outputs and the independent variable.
"""
from pythonfmu3 import Boolean, Dimension, Float64, Int32, String
from pythonfmu3 import Fmi3Causality as Fmi2Causality
from pythonfmu3 import Fmi3Slave
from pythonfmu3 import Fmi3Status as Fmi2Status
from pythonfmu3 import Fmi3Variability as Fmi2Variability
from pythonfmu3.default_experiment import DefaultExperiment

Real, Integer = Float64, Int32
# pythonfmu3 takes the model class from the script's text: the first class whose bases name
# its slave class. The base below is an alias, so the model class (added at the end of the
# script by the build) is the one found.
_Fmi3Base = Fmi3Slave
_MODEL_TEXT = ("description", "author", "license", "version", "copyright", "default_experiment")


class Fmi2Slave(_Fmi3Base):
    """A pythonfmu slave class on pythonfmu3's base."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name in _MODEL_TEXT:      # pythonfmu reads these from the class, pythonfmu3 from self
            value = getattr(type(self), name, None)
            if value is not None:
                setattr(self, name, value)

    def set_float64(self, vrs, values):
        self.set_real(vrs, values)

    def set_real(self, vrs, values):
        _Fmi3Base.set_float64(self, vrs, values)



class Fmi3Model:
    """What an FMI 3.0 model adds to its slave class (the build's last class in the script,
    `class <Model>(Fmi3Model, <Model>, Fmi3Slave)`): after every scalar, so that value
    references stay those of the FMI 2.0 FMU, the slave's ARRAYS (name -> (scalar outputs,
    description)) as Float64 array outputs, and the independent variable time."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, (elements, description) in getattr(self, "ARRAYS", {}).items():
            var = Float64(name, causality=Fmi2Causality.output,
                          variability=Fmi2Variability.continuous, description=description,
                          getter=lambda e=elements: [float(getattr(self, n)) for n in e])
            # set here, not by dimensions=: that imports numpy, which the FMU does not carry
            var._dimensions = [Dimension(start=str(len(elements)))]
            self.register_variable(var)
        self.time = 0.0
        self.register_variable(Float64("time", causality=Fmi2Causality.independent,
                                       variability=Fmi2Variability.continuous,
                                       description="simulation time"))

    def setup_experiment(self, start_time):
        self.time = start_time
        super().setup_experiment(start_time)

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return super().do_step(current_time, step_size)
