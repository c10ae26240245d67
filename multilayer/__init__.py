"""multilayer: fluid–multi-layered-structure interaction.

Incompressible flow in a 2D compliant channel coupled, by the kinematically
coupled scheme, to a wall made of a stack of thin and thick layers.  Every
model (layer, fluid, coupler) is a pluggy plugin; scenes are TOML case files.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("multilayer")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"

__all__ = ["__version__"]
