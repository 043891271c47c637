"""Result files: VTU frames and their ``.pvd`` series, ``result.npz``, ``summary.json``."""
