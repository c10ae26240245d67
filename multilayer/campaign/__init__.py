"""Many runs of one scene: variants, the executor (processes or Dask), and compare, study, stability, sweep."""
