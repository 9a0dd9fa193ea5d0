"""How the project's FMUs (and packages of them) are built.

Imported as ``papwc.build``. What it writes (``*.fmu``, ``*.ssp``) is not committed.
"""
