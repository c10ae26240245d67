"""``multilayer check-plugin NAME``: run the conformance checks of a layer plugin (:mod:`multilayer.testing`)."""

from __future__ import annotations

import argparse
import sys

import attrs

from multilayer.case.keys import parse_value
from multilayer.commands.common import FAILED, INVALID, OK, plugin_options
from multilayer.plugin.registry import Registry, nearest
from multilayer.testing import check_layer, example_params


@attrs.frozen
class CheckPluginOptions:
    """``multilayer check-plugin``."""

    name: str  #: the layer, as a case file names it
    params: tuple[str, ...]  #: ``--param KEY=VALUE``, changing the plugin's example
    registry: Registry

    @classmethod
    def from_args(cls, args: argparse.Namespace, registry: Registry, command_line: str) -> CheckPluginOptions:
        return cls(args.name, tuple(args.params), registry)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("check-plugin", help="run the conformance checks of a layer plugin (multilayer.testing)")
    p.add_argument("name", help="the layer's name, as a case file writes it")
    p.add_argument("--param", dest="params", action="append", default=[], metavar="KEY=VALUE",
                   help="a parameter to build the layer with, changing the plugin's example")
    plugin_options(p)
    p.set_defaults(handler=check_plugin, options=CheckPluginOptions.from_args)


def check_plugin(options: CheckPluginOptions) -> int:
    """``multilayer check-plugin NAME``: 0 when every check passes, 1 when one fails, 2 for an unknown name (130, 143
    stopped by SIGINT, SIGTERM: :mod:`multilayer.commands`)."""
    registry, name = options.registry, options.name
    found = registry.find("layer", name)
    if found is None:
        other = next((r for r in registry.all() if r.name == name), None)
        if other is not None:
            print(f"{name!r} is a {other.kind} plugin; check-plugin checks layer plugins", file=sys.stderr)
            return INVALID
        hint = nearest(name, registry.names("layer"))
        print(f"no layer plugin named {name!r}" + (f"; did you mean {hint!r}?" if hint else "")
              + registry.failure_note(), file=sys.stderr)
        return INVALID
    params = example_params(found.record)  # --param changes the plugin's example
    for item in options.params:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            print(f"--param {item!r}: expected KEY=VALUE, e.g. --param young=1e6", file=sys.stderr)
            return INVALID
        params[key.strip()] = parse_value(value)
    kind = "thin" if found.record.thin else "thick"
    print(f"check-plugin {name} ({found.package} {found.version}), a {kind} layer")
    results = check_layer(name, params, registry)
    for result in results:
        print(f"  {result}")
    failed = sum(not r.ok for r in results)
    print(f"{failed} of {len(results)} checks failed" if failed else f"all {len(results)} checks passed")
    return FAILED if failed else OK
