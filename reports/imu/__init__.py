"""Multi-axis IMU calibration: the matrix per temperature and its report section."""
