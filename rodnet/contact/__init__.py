"""Net-body contact: rigid body shapes and their signed distance, penalty and friction laws, and
the selection of contact points along thread segments (building blocks); the bodies of a scene
(:mod:`~rodnet.contact.bodies`), their forces and tangents on the lumped model's nodes
(:mod:`~rodnet.contact.forces`, :mod:`~rodnet.contact.lumped`) and what a run writes about them
(:mod:`~rodnet.contact.output`). Equations: ``elements/contact/FORMULATION.md``; user guide:
``docs/contact.md``.
"""
