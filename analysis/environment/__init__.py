"""The vendor notes' environment tests: drive interference, magnetic sensitivity, tilt linearity."""
