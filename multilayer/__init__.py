"""multilayer: fluid–multi-layered-structure interaction.

Incompressible flow in a 2D compliant channel coupled, by the kinematically
coupled scheme, to a wall made of a stack of thin and thick layers.  Every
model (layer, fluid, coupler) is a pluggy plugin; scenes are TOML case files.

The Python API (:mod:`multilayer.api`, ``docs/python-api.md``)::

    import multilayer as ml

    case = ml.load_case("cases/pulse-koiter-thick.toml", {"time.end": 0.004})
    res = ml.run(case)                        # or ml.run(case, "results/pulse") for a results folder
    print(res.status, res.peaks, res.max_relative_residual)
"""

__all__ = [
    "ArgumentError",
    "Case",
    "CaseError",
    "Results",
    "ResultsError",
    "RunFailed",
    "Step",
    "__version__",
    "load_case",
    "read_results",
    "run",
    "steps",
]


def __getattr__(name: str):
    """The API's names and ``__version__``, imported when first asked for: ``import multilayer`` itself imports
    nothing.

    (The API brings numpy, scipy and scikit-fem with it; every ``multilayer`` command and every worker of
    a sweep imports this package, most without wanting the API.  The version is read from the installed
    package's metadata, which takes longer than the console script may wait before it takes SIGINT and
    SIGTERM over: :func:`multilayer.commands.console`.)
    """
    if name == "__version__":
        from multilayer.version import __version__

        return __version__
    if name in __all__:
        from multilayer import api

        return getattr(api, name)
    raise AttributeError(f"module 'multilayer' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
