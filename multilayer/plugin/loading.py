"""Loading plugins: the installed ones (entry points) plus modules named on the command line (``--plugin``)."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from multilayer.plugin.interrupts import UserInterrupt
from multilayer.plugin.registry import Registry, RegistryError, import_failure


def import_plugin(spec: str) -> ModuleType:
    """Import a plugin module from a dotted name or a ``.py`` file (the current folder is searched).

    Raises RegistryError when it cannot be imported: whatever the module
    raises, ``sys.exit`` (``SystemExit``) and ``KeyboardInterrupt`` too, is
    a plugin that cannot be loaded, not the end of the command.
    """
    try:
        if spec.endswith(".py"):
            path = Path(spec)
            if not path.is_file():
                raise FileNotFoundError(f"no such file {spec!r}")
            module_spec = importlib.util.spec_from_file_location(path.stem, path)
            module = importlib.util.module_from_spec(module_spec)
            module_spec.loader.exec_module(module)
            return module
        if "" not in sys.path and str(Path.cwd()) not in sys.path:
            sys.path.insert(0, str(Path.cwd()))
        return importlib.import_module(spec)
    except UserInterrupt:  # Ctrl-C while loading: the command stops
        raise
    except (Exception, SystemExit, KeyboardInterrupt) as exc:  # a user's module: anything means "cannot load it"
        raise RegistryError(f"--plugin {spec}: cannot import it ({import_failure(exc)})") from None


def load_registry(plugins: Sequence[str] = (), warn: bool = True) -> Registry:
    """Installed plugins plus the ``--plugin`` modules.

    An installed plugin that fails to load is skipped, with a warning on
    stderr when ``warn``.
    """
    return Registry.load(extra=[import_plugin(p) for p in plugins], warn=warn)
