"""Many runs of one scene: variants, their grid, the executor (processes or Dask), and compare, study, stability, sweep.

The logic of those commands lives here and returns results or raises;
their command lines, messages and exit codes are :mod:`multilayer.commands`'s,
which this package never imports.
"""
