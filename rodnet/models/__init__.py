"""Thread models (lumped, Kirchhoff, Cosserat), the system that composes one with contact, and
the registry that maps ``model.type`` to them (:mod:`rodnet.models.registry`)."""
