"""The procedure's modes: the one list (CLI, GUI, settings, certificate), importable light."""

MODE_MULTISINE = "multisine"
MODE_STEPPED_SINE = "stepped-sine"
MODES = (MODE_MULTISINE, MODE_STEPPED_SINE)
