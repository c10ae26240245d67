"""The ``multilayer`` command line: one module per command, exit codes and shared options in one place."""
