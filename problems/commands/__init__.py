"""The `mixvi` commands: solve, check, figures, scenes, study, bench, extremes."""
