"""pythonfmu slaves: thin wrappers that expose the block maths as FMI 2.0 co-simulation FMUs.

Each module is turned into a self-contained, uniquely named FMU script by ``models/build.py``:
lines ending in ``# inline`` that import from ``mecanum_fmu.models.blocks`` (the maths) or from
``mecanum_fmu.models.slaves.feedthrough`` (the base class of the direct-feedthrough blocks) are
replaced by the source of that module, because pythonfmu loads the script as a top-level module
from ``resources/``.

Class attributes read by the build (not by pythonfmu):
    UNITS         variable name -> unit symbol (declared in UnitDefinitions)
    DEPENDENCIES  output name -> the inputs it depends on directly (ModelStructure/Outputs)
    INITIAL_DEPENDENCIES  output name -> knowns it depends on during initialization
"""
