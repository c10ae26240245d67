"""Case files: the frozen case model, reading and validating TOML, ``--set``/``--vary`` keys, sweep grids."""
