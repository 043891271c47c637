"""Pure array kernels: no classes, no configuration, no sparse matrices."""
