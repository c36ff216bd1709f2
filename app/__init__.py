"""accelcal: accelerometer calibration by comparison with multisine excitation."""
