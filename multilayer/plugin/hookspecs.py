"""The plugin hooks of multilayer: the only contract between the core and a model.

A plugin is any module or object with functions marked ``@hookimpl``.  Each
hook returns an iterable of small frozen records (see :mod:`multilayer.plugin.records`);
the registry flattens them, sorts them by name and rejects two records with
one name.  Built-in models are registered exactly like a third party's:
through the ``multilayer`` entry-point group.

A third-party package declares, in its ``pyproject.toml``::

    [project.entry-points.multilayer]
    my-layer = "my_package.my_layer"

and ``my_package/my_layer.py`` holds::

    from multilayer.plugin.hookspecs import hookimpl
    from multilayer.plugin.records import LayerPlugin, Param

    @hookimpl
    def multilayer_layers():
        return [LayerPlugin(name="my-layer", factory=MyLayer, params=(...), doc="...")]
"""

from __future__ import annotations

from collections.abc import Iterable

import pluggy

from multilayer.plugin.records import (
    BoundaryPlugin,
    CouplerPlugin,
    FluidPlugin,
    GeometryPlugin,
    LayerPlugin,
    SchemePlugin,
)

PROJECT = "multilayer"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def multilayer_layers() -> Iterable[LayerPlugin]:
    """Wall-layer models this plugin provides.

    A layer is thin (it lives on an interface line, unknown: radial
    displacement η) or thick (a radial band, unknown: displacement d).
    The factory receives the validated parameters as keyword arguments and
    returns a :class:`multilayer.wall.layer.ThinLayer` or
    :class:`multilayer.wall.layer.ThickLayer`.

    Example::

        >>> from multilayer.plugin.records import LayerPlugin, Param
        >>> @hookimpl
        ... def multilayer_layers():
        ...     return [LayerPlugin(name="stiff-membrane", factory=dict,
        ...                         params=(Param("tension", "C1", unit="dyn/cm"),),
        ...                         doc="A membrane under tension.")]
        >>> [r.name for r in multilayer_layers()]
        ['stiff-membrane']
    """


@hookspec
def multilayer_fluids() -> Iterable[FluidPlugin]:
    """Fluid models this plugin provides.

    The factory receives the validated parameters as keyword arguments and
    returns a :class:`multilayer.fluid.contract.Fluid`.

    Example::

        >>> from multilayer.plugin.records import FluidPlugin, Param
        >>> @hookimpl
        ... def multilayer_fluids():
        ...     return [FluidPlugin(name="inviscid", factory=dict,
        ...                         params=(Param("density", "ρ_f", unit="g/cm³", gt=0),),
        ...                         doc="An ideal fluid.")]
        >>> multilayer_fluids()[0].params[0].name
        'density'
    """


@hookspec
def multilayer_couplers() -> Iterable[CouplerPlugin]:
    """Couplers (time-stepping schemes that drive a scene) this plugin provides.

    The factory receives the validated parameters as keyword arguments and
    returns a :class:`multilayer.coupling.contract.Coupler`.

    Example::

        >>> from multilayer.plugin.records import CouplerPlugin
        >>> @hookimpl
        ... def multilayer_couplers():
        ...     return [CouplerPlugin(name="frozen", factory=dict, doc="Nothing moves.")]
        >>> multilayer_couplers()[0].doc
        'Nothing moves.'
    """


@hookspec
def multilayer_geometries() -> Iterable[GeometryPlugin]:
    """Geometries this plugin provides: what the meridian plane (z, r) of a scene stands for.

    The factory receives the validated parameters (the keys of ``[geometry]``
    besides ``model``, ``length`` and ``radius``) as keyword arguments and
    returns a :class:`multilayer.geometry.contract.Geometry`, which owns the
    measure of every integral of the scene.

    Example::

        >>> from multilayer.plugin.records import GeometryPlugin, Param
        >>> @hookimpl
        ... def multilayer_geometries():
        ...     return [GeometryPlugin(name="deep-channel", factory=dict,
        ...                            params=(Param("depth", unit="cm", gt=0),),
        ...                            doc="A planar channel of a given depth.")]
        >>> multilayer_geometries()[0].params[0].name
        'depth'
    """


@hookspec
def multilayer_boundaries() -> Iterable[BoundaryPlugin]:
    """Boundary conditions for the open ends of the fluid (inlet, outlet) this plugin provides.

    The factory receives the validated parameters (the keys of the end's
    table besides ``model``) as keyword arguments (and ``context=`` when the
    record asks for it) and returns a
    :class:`multilayer.boundary.contract.BoundaryCondition`.

    Example::

        >>> from multilayer.plugin.records import BoundaryPlugin, Param
        >>> @hookimpl
        ... def multilayer_boundaries():
        ...     return [BoundaryPlugin(name="resistance", factory=dict,
        ...                            params=(Param("resistance", "R", unit="dyn·s/cm⁴", ge=0),),
        ...                            doc="p = R Q.")]
        >>> multilayer_boundaries()[0].name
        'resistance'
    """


@hookspec
def multilayer_schemes() -> Iterable[SchemePlugin]:
    """Time schemes this plugin provides: what a coupler's ``scheme`` parameter names.

    The factory receives the validated parameters (the keys of a
    ``scheme = {model = "<name>", ...}`` table besides ``model``) as keyword
    arguments and returns a :class:`multilayer.numerics.timescheme.TimeScheme`:
    its stages' weights, its energy identity, its order, its error estimate.

    Example::

        >>> from multilayer.plugin.records import Param, SchemePlugin
        >>> @hookimpl
        ... def multilayer_schemes():
        ...     return [SchemePlugin(name="theta", factory=dict,
        ...                          params=(Param("theta", "θ", "1", default=1.0, gt=0.0, le=1.0),),
        ...                          doc="The θ-method.")]
        >>> multilayer_schemes()[0].params[0].default
        1.0
    """
