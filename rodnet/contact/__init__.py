"""Net-body contact: rigid body shapes and their signed distance, penalty and friction laws, and
the selection of contact points along thread segments (building blocks); the bodies of a scene
(:mod:`~rodnet.contact.bodies`), their forces and tangents on the nodes
(:mod:`~rodnet.contact.forces`), and the contact term any thread model carries
(:mod:`~rodnet.contact.term`). Equations: ``elements/contact/FORMULATION.md``; user guide:
``docs/contact.md``.
"""
