"""The validation report of ``rodnet validate --report DIR`` (:mod:`rodnet.report.build`)."""
