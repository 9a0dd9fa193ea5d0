"""The paper reproduced: its formulas (:mod:`.paper`), its simulation claims under the readings
the paper leaves open (:mod:`.claims`, :mod:`.readings`, :mod:`.run_metrics`,
:mod:`.claim_runs`) and ``papwc reproduce``'s figures, tables and report
(:mod:`.reproduction`)."""
