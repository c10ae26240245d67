"""The old key ``kind`` where a case file names a plugin: every occurrence reported at once, then set aside.

Every table that builds a plugin (or a load) names it with ``model``:
``[geometry]``, ``[fluid]``, ``[coupler]``, each ``[[layers]]``, each
``[loads]`` value, and the tables nested in them (an end's ``flow``, a
coupler's ``scheme``).  The geometry, the ends, the loads and the schemes
were once named with ``kind``; :func:`old_model_keys` finds that key in
all of them in one pass, one problem each with the line to write, and
returns the data with ``kind`` read as ``model`` (dropped when ``model`` is
given too), so that validation goes on to report the case's other
problems instead of a missing ``model`` at each of them.  No plugin has a
parameter named ``kind``: in these tables it is never anything else.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from multilayer.plugin.problems import Problem, old_model_problems
from multilayer.plugin.records import MODEL, OLD_MODEL

#: the sections that are a table naming a plugin; ``layers`` is an array of them, ``loads`` a table of them
PLUGIN_SECTIONS = ("geometry", "fluid", "coupler")


def old_model_keys(data: Mapping[str, Any]) -> tuple[Mapping[str, Any], list[Problem]]:
    """(``data`` with ``kind`` read as ``model``, a problem at each ``kind``); ``data`` itself is left as it is.

    >>> data = {"geometry": {"kind": "axisymmetric", "length": 6.0},
    ...         "loads": {"inlet": {"kind": "flow-rate", "flow": {"kind": "table", "file": "q.csv"}}}}
    >>> fixed, problems = old_model_keys(data)
    >>> print(*problems, sep="\\n")
    geometry.kind = 'axisymmetric': plugins are chosen by 'model', not 'kind'; write model = "axisymmetric"
    loads.inlet.kind = 'flow-rate': plugins are chosen by 'model', not 'kind'; write model = "flow-rate"
    loads.inlet.flow.kind = 'table': plugins are chosen by 'model', not 'kind'; write model = "table"
    >>> fixed["loads"]["inlet"]
    {'model': 'flow-rate', 'flow': {'model': 'table', 'file': 'q.csv'}}
    >>> old_model_keys({"coupler": {"model": "monolithic"}})[1]
    []
    """
    if not isinstance(data, Mapping):
        return data, []
    problems: list[Problem] = []
    fixed = dict(data)
    for section in PLUGIN_SECTIONS:
        if section in fixed:
            fixed[section] = _table(fixed[section], section, problems)
    if isinstance(fixed.get("layers"), list):
        fixed["layers"] = [_table(layer, f"layers[{i}]", problems) for i, layer in enumerate(fixed["layers"])]
    if isinstance(fixed.get("loads"), Mapping):
        fixed["loads"] = {key: _table(value, f"loads.{key}", problems) for key, value in fixed["loads"].items()}
    return (fixed, problems) if problems else (data, [])


def _table(value: Any, path: str, problems: list[Problem]) -> Any:
    """``value`` (a table naming a plugin, at ``path``) with ``kind`` set aside, and the tables nested in it."""
    if not isinstance(value, Mapping):
        return value
    problems += old_model_problems(value, path)
    fixed = {key: _table(v, f"{path}.{key}", problems) for key, v in value.items() if key != OLD_MODEL}
    if OLD_MODEL in value and MODEL not in value:
        fixed = {MODEL: value[OLD_MODEL], **fixed}
    return fixed
