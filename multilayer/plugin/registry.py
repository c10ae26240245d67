"""The plugin registry: entry points in, sorted and de-duplicated records out.

Loading follows tox's manager: the hookspecs first, then every module of the
``multilayer`` entry-point group (built-ins included), then any plugin object
a caller registers by hand (a test module, a notebook), then
``check_pending``.  Each hook implementation is called on its own so that a
record is always attributed to the package that provided it; pluggy's call
order is never relied on.

An installed plugin that cannot be loaded — its module fails to import, or
pluggy rejects its hooks — is skipped with one warning line on stderr
(:class:`FailedPlugin`), so that it does not break every command for cases
that do not use it; :attr:`Registry.failed` keeps it for the messages of a
case that names one of its models.
"""

from __future__ import annotations

import difflib
import importlib.metadata
import sys
from collections.abc import Iterable, Mapping
from types import ModuleType
from typing import Any

import attrs
import pluggy

from multilayer.plugin import hookspecs
from multilayer.plugin.interrupts import UserInterrupt
from multilayer.plugin.records import (
    MODEL,
    OLD_MODEL,
    PluginRecord,
    Registered,
    old_model_text,
)

HOOKS = {
    "layer": "multilayer_layers",
    "fluid": "multilayer_fluids",
    "coupler": "multilayer_couplers",
    "geometry": "multilayer_geometries",
    "boundary": "multilayer_boundaries",
    "scheme": "multilayer_schemes",
}


class RegistryError(Exception):
    """A plugin set that cannot be used (two plugins claim one name, a bad record)."""


@attrs.frozen
class FailedPlugin:
    """An installed plugin (entry point) that could not be loaded, and why.

    >>> print(FailedPlugin("my-layer", "my_package.layer", "my-package 1.0", "ModuleNotFoundError: No module named 'x'"))
    plugin entry point 'my-layer' (my_package.layer, from my-package 1.0) failed to load and is skipped: \
ModuleNotFoundError: No module named 'x'
    """

    name: str  #: the entry point's name
    value: str  #: what it points at, ``module[:attribute]``
    package: str  #: distribution name and version
    error: str  #: the exception, in one line

    def __str__(self) -> str:
        return (f"plugin entry point {self.name!r} ({self.value}, from {self.package}) failed to load and is "
                f"skipped: {self.error}")


#: entry points already reported in this process: each is reported once, however often plugins are loaded
_REPORTED: set[tuple[str, str]] = set()


def _report(failed: FailedPlugin) -> None:
    key = (failed.name, failed.value)
    if key not in _REPORTED:
        _REPORTED.add(key)
        print(f"multilayer: warning: {failed}", file=sys.stderr)


def _load_entry_points(pm: pluggy.PluginManager) -> tuple[dict[int, tuple[str, str]], list[FailedPlugin]]:
    """Register every module of the ``multilayer`` entry-point group that loads.

    Returns the (package, version) of each registered plugin by ``id`` and
    the entry points that failed to load.
    """
    dists: dict[int, tuple[str, str]] = {}
    failed: list[FailedPlugin] = []
    for dist in importlib.metadata.distributions():
        for ep in dist.entry_points:
            if ep.group != hookspecs.PROJECT or pm.get_plugin(ep.name) or pm.is_blocked(ep.name):
                continue
            name, version = dist.metadata["Name"], dist.version
            try:
                plugin = ep.load()
                pm.register(plugin, name=ep.name)
            except UserInterrupt:  # Ctrl-C while loading: the command stops
                raise
            except (Exception, SystemExit, KeyboardInterrupt) as exc:  # a third party's module: "cannot load it"
                failed.append(FailedPlugin(ep.name, ep.value, f"{name} {version}", import_failure(exc)))
                continue
            dists[id(plugin)] = (name, version)
    return dists, failed


def import_failure(exc: BaseException, who: str = "the module") -> str:
    """What a plugin module raised while imported (or ``who`` else raised), in one line (``sys.exit`` named as such).

    >>> import_failure(SystemExit(3)), import_failure(SystemExit()), import_failure(ValueError("no"))
    ('SystemExit: the module called sys.exit(3) while imported', 'SystemExit: the module called sys.exit() while imported', 'ValueError: no')
    >>> import_failure(KeyboardInterrupt()), import_failure(SystemExit(0), "the hook")
    ('KeyboardInterrupt: raised by the module while imported', 'SystemExit: the hook called sys.exit(0)')
    """
    when = " while imported" if who == "the module" else ""
    if isinstance(exc, SystemExit):
        code = "" if exc.code is None else repr(exc.code)
        return f"SystemExit: {who} called sys.exit({code}){when}"
    if isinstance(exc, KeyboardInterrupt):
        return f"KeyboardInterrupt: raised by {who}{when}"
    return f"{type(exc).__name__}: {exc}"


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


def _distribution_of(dists: dict[int, tuple[str, str]], plugin: object) -> tuple[str, str]:
    if id(plugin) in dists:
        return dists[id(plugin)]
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
    >>> from multilayer.plugin.hookspecs import hookimpl
    >>> from multilayer.plugin.records import GeometryPlugin
    >>> class Geometries:  # a plugin registered by hand (Registry.load() adds the installed ones, entry points)
    ...     @hookimpl
    ...     def multilayer_geometries(self):
    ...         return [GeometryPlugin(name="flat", factory=dict, doc="A stand-in.")]
    >>> reg = Registry.load([Geometries()], entry_points=False)
    >>> reg.names("geometry"), reg.get("geometry", "flat").record.doc, reg.names("layer")
    (['flat'], 'A stand-in.', [])
    """

    def __init__(self, pm: pluggy.PluginManager, dists: dict[int, tuple[str, str]] | None = None,
                 failed: Iterable[FailedPlugin] = ()):
        self.pm = pm
        self._dists = dists or {}
        #: installed plugins that could not be loaded (skipped)
        self.failed: list[FailedPlugin] = list(failed)
        self._by_kind: dict[str, dict[str, Registered]] = {}
        self._collect()

    @classmethod
    def load(cls, extra: Iterable[object] = (), entry_points: bool = True, warn: bool = True) -> Registry:
        """Entry-point plugins plus ``extra`` plugin objects registered by hand.

        An entry point that fails to load is skipped and, with ``warn``,
        reported on stderr (once per process).  A plugin in ``extra`` that
        pluggy rejects raises :class:`RegistryError`: it was asked for.
        """
        pm = pluggy.PluginManager(hookspecs.PROJECT)
        pm.add_hookspecs(hookspecs)
        dists, failed = _load_entry_points(pm) if entry_points else ({}, [])
        extra = list(extra)
        for plugin in extra:
            if not pm.is_registered(plugin):
                try:
                    pm.register(plugin)
                except (ValueError, pluggy.PluginValidationError) as exc:
                    raise RegistryError(f"cannot register {_plugin_name(plugin)}: {exc}") from None
        while True:
            try:
                pm.check_pending()
                break
            except pluggy.PluginValidationError as exc:  # a hook of no known name
                if any(exc.plugin is plugin for plugin in extra):
                    raise RegistryError(f"{_plugin_name(exc.plugin)}: {exc}") from None
                name = pm.get_name(exc.plugin)
                pm.unregister(exc.plugin)
                failed.append(FailedPlugin(name, _plugin_name(exc.plugin), " ".join(dists.pop(id(exc.plugin), ("?",))),
                                           f"PluginValidationError: {exc}"))
        if warn:
            for failure in failed:
                _report(failure)
        return cls(pm, dists, failed)

    def _collect(self) -> None:
        for kind, hook_name in HOOKS.items():
            table: dict[str, Registered] = {}
            for impl in getattr(self.pm.hook, hook_name).get_hookimpls():
                package, version = _distribution_of(self._dists, impl.plugin)
                try:
                    records = list(impl.function() or ())
                except UserInterrupt:
                    raise
                except (Exception, SystemExit, KeyboardInterrupt) as exc:  # a third party's hook: "cannot load it"
                    raise RegistryError(f"{hook_name} of package {package!r} ({impl.plugin_name}) failed when "
                                        f"called: {import_failure(exc, 'the hook')}") from None
                for record in records:
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
            raise KeyError(msg + self.failure_note())
        return found

    def build(self, kind: str, spec: str | Mapping[str, Any]) -> Any:
        """The plugin of ``kind`` that ``spec`` names, built: a name, or a table ``{model = name, ...its
        parameters}`` (the parameters it leaves out take their defaults).  Checks nothing the case
        validator checks; a name that is not registered is a KeyError (:meth:`get`), a table with the old
        key ``kind`` a ValueError.

        >>> from multilayer.plugin.hookspecs import hookimpl
        >>> from multilayer.plugin.records import Param, SchemePlugin
        >>> class Schemes:  # a stand-in plugin, whose "scheme" is the dict of its parameters
        ...     @hookimpl
        ...     def multilayer_schemes(self):
        ...         return [SchemePlugin(name="theta", factory=dict, params=(Param("theta", unit="1", default=1.0),),
        ...                              doc="The θ-method.")]
        >>> reg = Registry.load([Schemes()], entry_points=False)
        >>> reg.build("scheme", "theta"), reg.build("scheme", {"model": "theta", "theta": 0.5})
        ({'theta': 1.0}, {'theta': 0.5})
        >>> reg.build("scheme", {"kind": "theta"})
        Traceback (most recent call last):
        ...
        ValueError: kind = 'theta': plugins are chosen by 'model', not 'kind'; write model = "theta"
        """
        if isinstance(spec, str):
            name, given = spec, {}
        else:
            if OLD_MODEL in spec:
                raise ValueError(f"{OLD_MODEL} = {spec[OLD_MODEL]!r}: " + "; ".join(old_model_text(spec)))
            name, given = spec[MODEL], {k: v for k, v in spec.items() if k != MODEL}
        record = self.get(kind, name).record
        params = {p.name: p.default for p in record.params if not p.required}
        return record.factory(**{**params, **given})

    def arguments(self, record: PluginRecord, params: Mapping[str, Any]) -> dict[str, Any]:
        """``params`` as ``record``'s factory takes them: a parameter that names a plugin (:attr:`Param.plugin`,
        e.g. a coupler's ``scheme``) is that plugin, built (:meth:`build`); an unset one stays None."""
        out = dict(params)
        for param in record.params:
            if param.plugin is not None and out.get(param.name) is not None:
                out[param.name] = self.build(param.plugin, out[param.name])
        return out

    def failure_note(self) -> str:
        """``"; note: plugin entry point 'x' (...) failed to load ..."`` when one did, else ``""``.

        Added to the message of a model name that is not found: the model may
        be one of the plugin's.
        """
        return "".join(f"; note: {failure}" for failure in self.failed)

    def all(self) -> list[Registered]:
        return [r for kind in HOOKS for r in self._by_kind[kind].values()]


def _plugin_name(plugin: object) -> str:
    return plugin.__name__ if isinstance(plugin, ModuleType) else repr(plugin)


def plugin_versions(case, registry: Registry) -> dict[str, dict[str, str]]:
    """Which package and version provides every model of ``case``, by its key path (``coupler``, ``layers[0]``...)."""
    specs = [("coupler", case.coupler.path, case.coupler.model),
             *(("layer", s.path, s.model) for s in case.layers)]
    if case.fluid is not None:
        specs.append(("fluid", case.fluid.path, case.fluid.model))
    specs.append(("geometry", "geometry", case.geometry.model))
    loads = case.resolved.get("loads") or {}
    specs += [("boundary", f"loads.{end}", loads[end][MODEL]) for end in ("inlet", "outlet")
              if isinstance(loads.get(end), dict) and MODEL in loads[end]]
    record = registry.find("coupler", case.coupler.model)
    for param in record.record.params if record is not None else ():  # the plugins its parameters name
        value = case.coupler.params.get(param.name)
        if param.plugin is not None and value is not None:
            specs.append((param.plugin, f"{case.coupler.path}.{param.name}",
                          value if isinstance(value, str) else value[MODEL]))
    out = {}
    for kind, path, name in specs:
        reg = registry.find(kind, name)
        if reg is not None:
            out[path] = {"name": name, "package": reg.package, "version": reg.version}
    return out
