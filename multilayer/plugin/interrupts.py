"""A Ctrl-C the user gave, told apart from a ``KeyboardInterrupt`` a plugin module raised.

Loading plugins reports anything a plugin module raises while imported,
``KeyboardInterrupt`` included, as a plugin that cannot be loaded
(:func:`multilayer.plugin.registry.import_failure`).  A SIGINT that arrives
while the command imports its plugins must stop the command instead: the
command line's handler (:func:`on_sigint`) raises :class:`UserInterrupt`,
which the loaders let through.
"""

from __future__ import annotations


class UserInterrupt(KeyboardInterrupt):
    """SIGINT, delivered to the process (Ctrl-C): not a plugin's doing."""


def on_sigint(signum: int, frame: object) -> None:
    """A SIGINT handler: raise :class:`UserInterrupt`."""
    raise UserInterrupt
