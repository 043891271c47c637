"""Cosserat rods and nets of two-node Simo-Reissner elements."""
