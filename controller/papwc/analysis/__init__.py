"""The paper reproduced: its formulas (:mod:`.paper`), ``papwc reproduce`` (:mod:`.reproduce`),
its simulation claims under the readings the paper leaves open (:mod:`.claims`) and the plots
of runs (:mod:`.plots`)."""
