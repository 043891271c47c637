"""Element formulations: one file per element type, knowing its DOF layout."""
