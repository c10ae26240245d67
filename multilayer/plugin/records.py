"""Frozen records that plugins hand to the registry: the plugin and its parameters."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import attrs

#: Marker for a parameter that has no default and must be given.
REQUIRED: Any = attrs.make_class("Required", [], repr_ns=None)()

#: the key of a case-file table that names the plugin (or the load) the table builds: ``model = "windkessel"``
MODEL = "model"
#: the key that named the geometry, the ends, the loads and the schemes before ``model`` named every plugin;
#: refused where a table names its plugin, with the line to write (:func:`old_model_text`)
OLD_MODEL = "kind"


def old_model_text(table: Mapping[str, Any]) -> tuple[str, str]:
    """(what is wrong, what to write) about the old key ``kind`` in ``table``, a table that names a plugin.

    >>> old_model_text({"kind": "axisymmetric", "length": 6.0})
    ("plugins are chosen by 'model', not 'kind'", 'write model = "axisymmetric"')
    >>> old_model_text({"kind": "table", "model": "table"})
    ("plugins are chosen by 'model', not 'kind', and model = 'table' is given too", 'remove kind')
    """
    wrong = f"plugins are chosen by {MODEL!r}, not {OLD_MODEL!r}"
    if MODEL in table:
        return f"{wrong}, and {MODEL} = {table[MODEL]!r} is given too", f"remove {OLD_MODEL}"
    value = table[OLD_MODEL]
    return wrong, f"write {MODEL} = " + (json.dumps(value, ensure_ascii=False) if isinstance(value, str) else repr(value))


@attrs.frozen
class Param:
    """One parameter of a plugin, in physical units.

    Parameters
    ----------
    name : str
        The key a case file uses (``young``, ``density``, ...).
    symbol : str
        The symbol of the scheme (``E``, ``ρ₁``, ``C1``), for docs.
    unit : str
        Physical unit (CGS), e.g. ``dyn/cm²``; ``"1"`` for a dimensionless
        number (a ratio), empty for a count, a name or a switch.
    default : object
        Default value, or :data:`REQUIRED`; ``None`` means optional with no value.
    type : type
        ``float``, ``int``, ``str`` or ``bool``.  An ``int`` is accepted for a float.
    gt, ge, lt, le : float, optional
        Open/closed bounds checked by the case validator.
    choices : tuple of str, optional
        Allowed values of a string parameter.
    plugin : str, optional
        The kind of plugin the value names (``"scheme"``): the name of a registered plugin of that kind,
        or a table ``{model = name, ...its parameters}``; the validator checks it against the registry
        and the factory receives that plugin built (:meth:`multilayer.plugin.registry.Registry.arguments`).
    doc : str
        One line: what the parameter is.

    Examples
    --------
    >>> p = Param("poisson", "σ", gt=-1.0, lt=0.5, doc="Poisson ratio")
    >>> p.required
    True
    >>> p.bounds_text()
    '> -1.0 and < 0.5'
    """

    name: str
    symbol: str = ""
    unit: str = ""
    default: Any = REQUIRED
    type: type = float
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] | None = None
    doc: str = ""
    plugin: str | None = attrs.field(default=None, kw_only=True)

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def bounds_text(self) -> str:
        parts = []
        for op, val in ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le)):
            if val is not None:
                parts.append(f"{op} {val}")
        return " and ".join(parts)


@attrs.frozen
class PluginRecord:
    """What a plugin registers: a name, a factory, its parameter schema, one line of doc."""

    kind: ClassVar[str] = "plugin"

    name: str
    factory: Callable[..., Any]
    params: tuple[Param, ...] = attrs.field(default=(), converter=tuple)
    doc: str = ""

    def param(self, name: str) -> Param | None:
        for p in self.params:
            if p.name == name:
                return p
        return None


@attrs.frozen
class LayerPlugin(PluginRecord):
    """A wall-layer model. ``thin`` is True for an interface-line layer.

    ``example`` is a typical set of parameters (keyword only): the
    conformance kit (:mod:`multilayer.testing`, ``multilayer check-plugin``)
    builds the layer with it.
    """

    kind: ClassVar[str] = "layer"
    thin: bool = True
    example: dict[str, Any] | None = attrs.field(default=None, kw_only=True, eq=False)


@attrs.frozen
class FluidPlugin(PluginRecord):
    kind: ClassVar[str] = "fluid"


@attrs.frozen
class CouplerPlugin(PluginRecord):
    kind: ClassVar[str] = "coupler"


@attrs.frozen
class GeometryPlugin(PluginRecord):
    """A geometry: what the meridian plane (z, r) stands for, its measure (a
    :class:`multilayer.geometry.contract.Geometry`). ``[geometry] model`` names it; its parameters sit in
    ``[geometry]`` beside ``length`` and ``radius``."""

    kind: ClassVar[str] = "geometry"


@attrs.frozen
class BoundaryPlugin(PluginRecord):
    """A condition on an open end of the fluid (a :class:`multilayer.boundary.contract.BoundaryCondition`).

    A case names it as ``[loads] inlet = {model = "<name>", ...}`` (or ``outlet``).
    With ``context`` the factory also receives ``context=``, a
    :class:`multilayer.boundary.contract.BuildContext` (the key path, the case's
    folder for relative file names, the constants a formula may use).
    """

    kind: ClassVar[str] = "boundary"
    context: bool = attrs.field(default=False, kw_only=True)


@attrs.frozen
class SchemePlugin(PluginRecord):
    """A time scheme (a :class:`multilayer.numerics.timescheme.TimeScheme`): a coupler's ``scheme`` parameter
    names it (``[coupler] scheme = "<name>"``, or ``{model = "<name>", ...}`` with its parameters)."""

    kind: ClassVar[str] = "scheme"


@attrs.frozen
class Registered:
    """A record as the registry holds it: with the package that provided it."""

    record: PluginRecord
    package: str
    version: str

    @property
    def kind(self) -> str:
        return self.record.kind

    @property
    def name(self) -> str:
        return self.record.name
