"""Placeholder: being written (do not ship)."""
