"""The discrepancy workflow: which physical effect a gyro model lacks, fitted, with its own gap shown shrinking."""
