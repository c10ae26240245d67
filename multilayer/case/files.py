"""The files a case reads, read with bounds: regular files only, of a capped size, nested to a capped depth.

A case file or a table it names could be anything the file system holds:
a FIFO (reading it waits for a writer for ever), ``/dev/zero`` (endless),
a directory, a file of gigabytes, or TOML nested thousands of levels deep
(the parser recurses and fails with a ``RecursionError``).  Each is refused
here with a sentence, before it is parsed:

* :func:`read_case` reads and parses a case file within these bounds;
* :func:`~multilayer.functions.tablefile.read_bounded` (the tables' reader, below
  this package) opens without blocking, checks that the path is a regular
  file no larger than the cap, and reads at most the cap;
* :func:`toml_depth` scans TOML text for its deepest nesting of arrays and
  inline tables (strings and comments skipped), in linear time, before
  ``tomllib`` sees it; :func:`data_depth` measures parsed data (dotted keys
  nest tables without brackets).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from multilayer.functions.tablefile import (
    MAX_TABLE_BYTES,
    FileRefused,
    read_bounded,
    size_text,
)
from multilayer.plugin.problems import MISSING, CaseError, Problem

__all__ = ["MAX_CASE_BYTES", "MAX_DEPTH", "MAX_TABLE_BYTES", "FileRefused", "data_depth", "read_bounded", "read_case",
           "size_text", "toml_depth"]

#: The largest case file read (bytes): case files are a few kB.
MAX_CASE_BYTES = 1_000_000
#: The deepest nesting of tables and arrays a case file, a ``--set`` or a ``--vary`` value may have.
MAX_DEPTH = 32


_NEXT = re.compile(r'"""|\'\'\'|["\'#\[\]{}]')
_BASIC_REST = re.compile(r'(?:[^"\\\n]|\\.)*"')
_ML_BASIC_REST = re.compile(r'(?:[^"\\]|\\.|"(?!""))*"""', re.S)
_LITERAL_REST = re.compile(r"[^'\n]*'")


def toml_depth(text: str, stop: int | None = None) -> int:
    """The deepest nesting of arrays and inline tables in TOML ``text`` (brackets in strings and comments skipped).

    Linear in the length of ``text``; stops early once ``stop`` is passed.
    Text that is not TOML (an unterminated string) is scanned up to there:
    the parser then tells what is wrong with it.

    >>> toml_depth('a = [[1, 2], {b = "[[["}]  # ]]]')
    2
    >>> toml_depth("[[layers]]\\nx = 1"), toml_depth("v = " + "[" * 500 + "]" * 500)
    (2, 500)
    >>> toml_depth("s = '''[[[''' # [\\nt = \\"\\"\\"a\\\\\\"\\"\\"[\\"\\"\\"")
    0
    """
    depth = deepest = 0
    pos, n = 0, len(text)
    while pos < n:
        match = _NEXT.search(text, pos)
        if match is None:
            break
        token, pos = match.group(), match.end()
        if token in "[{":
            depth += 1
            deepest = max(deepest, depth)
            if stop is not None and deepest > stop:
                break
        elif token in "]}":
            depth = max(depth - 1, 0)
        elif token == "#":
            end = text.find("\n", pos)
            pos = n if end < 0 else end + 1
        else:
            if token == "'''":
                end = text.find("'''", pos)
                end = -1 if end < 0 else end + 3
            else:
                pattern = {'"""': _ML_BASIC_REST, '"': _BASIC_REST, "'": _LITERAL_REST}[token]
                rest = pattern.match(text, pos)
                end = -1 if rest is None else rest.end()
            if end < 0:  # unterminated: the parser reports it
                break
            pos = end
            if len(token) == 3:  # a multi-line string may end in one or two more quotes
                for _ in range(2):
                    if pos < n and text[pos] == token[0]:
                        pos += 1
    return deepest


def data_depth(data: Any, stop: int | None = None) -> tuple[int, list[str | int]]:
    """(depth, key steps to the deepest table or array) of parsed data: tables and arrays, each a level.

    Iterative, so that data nested deeper than the interpreter's recursion
    limit is measured too; stops early once ``stop`` is passed.

    >>> data_depth({"a": {"b": [1, {"c": 2}]}, "d": 1})
    (4, ['a', 'b', 1])
    >>> data_depth(5)
    (0, [])
    """
    deepest: tuple[int, list[str | int]] = (0, [])
    todo: list[tuple[Any, list[str | int]]] = [(data, [])]
    while todo:
        node, steps = todo.pop()
        if isinstance(node, Mapping):
            children = list(node.items())
        elif isinstance(node, list | tuple):
            children = list(enumerate(node))
        else:
            continue
        level = len(steps) + 1
        if level > deepest[0]:
            deepest = (level, steps)
            if stop is not None and level > stop:
                return level, steps
        todo.extend((child, [*steps, key]) for key, child in children)
    return deepest


def read_case(path: Path | str) -> dict[str, Any]:
    """The parsed TOML of a case file, read with bounds (:mod:`multilayer.case.files`).

    A directory, a FIFO, a device, a file over :data:`~multilayer.case.files.MAX_CASE_BYTES`,
    arrays or tables nested deeper than :data:`~multilayer.case.files.MAX_DEPTH`
    are refused before they are parsed.

    Raises
    ------
    CaseError
        At the file's path (or at the key path of tables nested too deeply).
    """
    where = str(path)
    try:
        raw = read_bounded(path, MAX_CASE_BYTES, "case file")
    except FileNotFoundError:
        raise CaseError([Problem(where, MISSING, "no such case file")]) from None
    except FileRefused as exc:
        raise CaseError([Problem(where, MISSING, str(exc))]) from None
    except OSError as exc:
        raise CaseError([Problem(where, MISSING, f"cannot read the case file ({exc})")]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError([Problem(where, MISSING, f"cannot read the case file ({exc})")]) from None
    if toml_depth(text, stop=MAX_DEPTH) > MAX_DEPTH:
        raise CaseError([Problem(where, MISSING, f"arrays or inline tables nested more than {MAX_DEPTH} levels "
                                                 f"deep; expected at most {MAX_DEPTH}")])
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError([Problem(where, MISSING, f"invalid TOML: {exc}")]) from None
    except RecursionError:  # (the scan above bounds what the parser recurses on)
        raise CaseError([Problem(where, MISSING, "nested too deeply for the TOML parser")]) from None
    depth, steps = data_depth(data, stop=MAX_DEPTH + 1)
    if depth > MAX_DEPTH + 1:  # dotted keys and table headers nest tables without brackets
        raise CaseError([Problem(path_text(steps) + "...", MISSING, f"tables or arrays nested more than {MAX_DEPTH} "
                                                                    f"levels deep; expected at most {MAX_DEPTH}")])
    return data


def path_text(steps: list[str | int]) -> str:
    """Key steps as a key path: ``['layers', 0, 'young']`` → ``layers[0].young``."""
    text = ""
    for s in steps:
        text += f"[{s}]" if isinstance(s, int) else (f".{s}" if text else str(s))
    return text
