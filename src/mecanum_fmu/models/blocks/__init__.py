"""The maths of each block of the original Simulink diagram, as plain functions.

Every module here uses the standard library only and no package-relative imports:
the FMU build inlines their source into self-contained slave scripts (see ``models/build.py``).
"""
