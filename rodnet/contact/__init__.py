"""Net-body contact: rigid body shapes and their signed distance, penalty and friction laws, and
the selection of contact points along thread segments. Equations: ``elements/contact/FORMULATION.md``.
"""
