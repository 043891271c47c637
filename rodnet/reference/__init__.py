"""Independent reference models used to validate rodnet."""
