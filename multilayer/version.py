"""The installed version of multilayer (what ``summary.json`` and checkpoints record)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("multilayer")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"
