"""The FMI glue of the project's FMUs (:mod:`.glue`), bundled into each FMU.

It imports pythonfmu and, relatively, the model layer; the FMUs bundle both
under a package name of their own.
"""
