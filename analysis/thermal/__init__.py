"""Temperature effects: bias and scale-factor sensitivity, warm-up, compensation tables."""
