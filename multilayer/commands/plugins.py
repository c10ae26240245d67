"""``multilayer plugins [NAME]``: the available models, or one model's parameters."""

from __future__ import annotations

import argparse
import sys

import attrs

from multilayer.commands.common import INVALID, OK, plugin_options
from multilayer.plugin.problems import describe
from multilayer.plugin.records import Param
from multilayer.plugin.registry import Registry, nearest

#: how a case file names a plugin of each kind: always by ``model``
CASE_LINES = {
    "layer": '[[layers]] model = "{name}"',
    "fluid": '[fluid] model = "{name}"',
    "coupler": '[coupler] model = "{name}"',
    "geometry": '[geometry] model = "{name}"',
    "boundary": '[loads] inlet = {{ model = "{name}", ... }} (or outlet)',
    "scheme": '[coupler] scheme = "{name}", or scheme = {{ model = "{name}", ... }} with its parameters',
}


@attrs.frozen
class PluginsOptions:
    """``multilayer plugins``."""

    name: str | None  #: a model whose parameters to show; None lists every plugin
    registry: Registry

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> PluginsOptions:
        return cls(args.name, registry)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("plugins", help="list the available models, or one model's parameters")
    p.add_argument("name", nargs="?", help="show the parameters of this model")
    plugin_options(p)
    p.set_defaults(handler=plugins, options=PluginsOptions.from_args)


def plugins(options: PluginsOptions) -> int:
    """``multilayer plugins``: 0 listed, 2 no plugin of that name."""
    registry, name = options.registry, options.name
    entries = registry.all()
    if name is not None:
        chosen = [r for r in entries if r.name == name]
        if not chosen:
            hint = nearest(name, [r.name for r in entries])
            print(f"no plugin named {name!r}" + (f"; did you mean {hint!r}?" if hint else "") + registry.failure_note(),
                  file=sys.stderr)
            return INVALID
        for entry in chosen:
            print(f"{entry.kind} {entry.name} ({entry.package} {entry.version}): {entry.record.doc}")
            print("in a case file: " + CASE_LINES[entry.kind].format(name=entry.name))
            rows = [("name", "unit", "default", "accepts", "doc")]
            rows += [_param_row(p) for p in entry.record.params]
            print(table(rows))
        return OK
    rows = [("kind", "name", "package", "version", "doc")]
    rows += [(r.kind, r.name, r.package, r.version, r.record.doc.strip().splitlines()[0] if r.record.doc.strip() else "")
             for r in entries]
    print(table(rows))
    return OK


def _param_row(param: Param) -> tuple[str, ...]:
    default = "required" if param.required else repr(param.default)
    return (param.name, param.unit, default, describe(param).split(" (")[0], param.doc)


def table(rows: list[tuple[str, ...]]) -> str:
    """The rows as text columns, each as wide as its widest cell.

    >>> print(table([("a", "bb"), ("ccc", "d")]))
    a    bb
    ccc  d
    """
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(str(c).ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows)
