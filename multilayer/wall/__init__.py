"""The wall: the layer contract and its checks, the stack assembled on one set of DOFs, the probe of a stack."""
