"""Plugins: the hook specifications, the records plugins register, the registry that loads them, and parameter checks."""
