"""Built-in multilayer plugins, registered through the ``multilayer`` entry-point group."""
