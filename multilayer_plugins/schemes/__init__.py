"""The built-in time schemes, one module each, registered like any other plugin (``multilayer_schemes``).

Each is a :class:`multilayer.numerics.timescheme.TimeScheme`: its weights, its energy identity, its
order, its error estimate for adaptive steps and where its geometry sits (docs/theory.md §4).
"""
