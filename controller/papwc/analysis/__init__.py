"""The paper reproduced: its formulas (:mod:`.paper`), ``papwc reproduce`` (:mod:`.reproduce`)
and the plots of runs (:mod:`.plots`)."""
