"""mecanum_fmu: a four-wheel mecanum car as FMI 2.0 co-simulation FMUs, and a master to run them."""
__version__ = "0.1.0"
