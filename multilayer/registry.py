"""The plugin registry: entry points in, sorted and de-duplicated records out.

Loading follows tox's manager: the hookspecs first, then every module of the
``multilayer`` entry-point group (built-ins included), then any plugin object
a caller registers by hand (a test module, a notebook), then
``check_pending``.  Each hook implementation is called on its own so that a
record is always attributed to the package that provided it; pluggy's call
order is never relied on.
"""

from __future__ import annotations

import difflib
import importlib.metadata
from collections.abc import Iterable
from types import ModuleType

import pluggy

from multilayer import hookspecs
from multilayer.records import PluginRecord, Registered

HOOKS = {
    "layer": "multilayer_layers",
    "fluid": "multilayer_fluids",
    "coupler": "multilayer_couplers",
}


class RegistryError(Exception):
    """A plugin set that cannot be used (two plugins claim one name, a bad record)."""


def nearest(name: str, candidates: Iterable[str]) -> str | None:
    """The closest valid name, for "did you mean" hints.

    >>> nearest("koiter", ["wave-membrane", "koiter-shell"])
    'koiter-shell'
    """
    candidates = list(candidates)
    hits = difflib.get_close_matches(name, candidates, n=1, cutoff=0.4)
    if hits:
        return hits[0]
    low = name.lower()
    for c in candidates:
        if low and (low in c.lower() or c.lower() in low):
            return c
    return None


def _distribution_of(pm: pluggy.PluginManager, plugin: object) -> tuple[str, str]:
    for plug, dist in pm.list_plugin_distinfo():
        if plug is plugin:
            return dist.project_name, dist.version
    module = plugin.__name__ if isinstance(plugin, ModuleType) else type(plugin).__module__
    package = module.split(".")[0]
    try:
        return package, importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return package, "unversioned"


class Registry:
    """All models available to a run, by kind and name.

    Examples
    --------
    >>> reg = Registry.load()
    >>> reg.get("layer", "wave-membrane").package
    'multilayer'
    """

    def __init__(self, pm: pluggy.PluginManager):
        self.pm = pm
        self._by_kind: dict[str, dict[str, Registered]] = {}
        self._collect()

    @classmethod
    def load(cls, extra: Iterable[object] = (), entry_points: bool = True) -> Registry:
        """Entry-point plugins plus ``extra`` plugin objects registered by hand."""
        pm = pluggy.PluginManager(hookspecs.PROJECT)
        pm.add_hookspecs(hookspecs)
        if entry_points:
            pm.load_setuptools_entrypoints(hookspecs.PROJECT)
        for plugin in extra:
            if not pm.is_registered(plugin):
                pm.register(plugin)
        pm.check_pending()
        return cls(pm)

    def _collect(self) -> None:
        for kind, hook_name in HOOKS.items():
            table: dict[str, Registered] = {}
            for impl in getattr(self.pm.hook, hook_name).get_hookimpls():
                package, version = _distribution_of(self.pm, impl.plugin)
                for record in impl.function() or ():
                    if not isinstance(record, PluginRecord) or record.kind != kind:
                        raise RegistryError(
                            f"{hook_name} of package {package!r} returned {record!r}; "
                            f"expected {kind} records"
                        )
                    entry = Registered(record, package, version)
                    if record.name in table:
                        other = table[record.name]
                        raise RegistryError(
                            f"two plugins claim the {kind} name {record.name!r}: "
                            f"package {other.package!r} ({other.version}) and "
                            f"package {package!r} ({version})"
                        )
                    table[record.name] = entry
            self._by_kind[kind] = dict(sorted(table.items()))

    def names(self, kind: str) -> list[str]:
        return list(self._by_kind[kind])

    def find(self, kind: str, name: str) -> Registered | None:
        return self._by_kind[kind].get(name)

    def get(self, kind: str, name: str) -> Registered:
        found = self.find(kind, name)
        if found is None:
            hint = nearest(name, self.names(kind))
            msg = f"no {kind} plugin named {name!r}"
            if hint:
                msg += f"; did you mean {hint!r}?"
            raise KeyError(msg)
        return found

    def all(self) -> list[Registered]:
        return [r for kind in HOOKS for r in self._by_kind[kind].values()]
