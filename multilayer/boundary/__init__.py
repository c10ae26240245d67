"""Boundary conditions: the contract of an open end of the fluid (inlet, outlet)."""
