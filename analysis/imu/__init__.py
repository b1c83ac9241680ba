"""Multi-axis IMU calibration: the misalignment/scale matrix per temperature, accelerometers, table checks."""
