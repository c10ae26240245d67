"""A run's scene: the setup built from a case (models, spaces, the fluid's discretization) and the state values."""
