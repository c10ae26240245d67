"""Couplers: the contract, and the kit a coupler's author needs (structure step, interface pieces, acceleration)."""
