"""Pictures and plots of results (pyvista, matplotlib): imported only when asked for."""
