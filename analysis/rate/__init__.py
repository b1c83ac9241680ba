"""Rate-table tests: dwell means, scale factor and nonlinearity, threshold, rate limits, frequency response."""
