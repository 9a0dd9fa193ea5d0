"""Studies behind the README's open bounds, each runnable as ``python -m papwc.studies.NAME``.

- :mod:`.ringing`: what pulses do to a flexible drive;
- :mod:`.drive_state`: planning pulses from a model of the flexible drive, and how exact it must be;
- :mod:`.scatter`: how far the same pulse moves a table whose breakaway is redrawn at every stop;
- :mod:`.ring_scan`: whether the pulse controllers ever see ringing on rigid tables;
- :mod:`.flexible_scatter`: the same pulse from a relaxed flexible drive;
- :mod:`.ceiling`: planning for the lowest breakaway with the table known, or part of it
  learned;
- :mod:`.one_pulse`: one sample on many candidate stick–slip tables at once, and the candidates
  the pulses leave;
- :mod:`.sliding`: the sliding friction from the slides after wide pulses;
- :mod:`.bound_physics`: why a hard per-pulse bound holds for one-sample pulses only from
  about 50 um of error (the figures of the spec's bound);
- :mod:`.counts`: the command line these share.
"""
