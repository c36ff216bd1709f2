"""The estimators' names: the one list (CLI, GUI, settings), importable without numpy/scipy."""

ESTIMATORS = ("periodic", "h1", "seed")
DEFAULT_ESTIMATOR = "periodic"
