"""The estimators' names: the one list (CLI, GUI, settings), importable without numpy/scipy."""

ESTIMATORS = ("periodic", "h1", "seed", "lpm")  # lpm: one record (dsp.lpm_record)
DEFAULT_ESTIMATOR = "periodic"
