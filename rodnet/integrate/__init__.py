"""Time integrators. They see a model through a few methods, never a rod or a net."""
