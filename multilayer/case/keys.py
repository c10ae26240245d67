"""Keys of a case file as the command line gives them: ``--set KEY=VALUE``, ``--vary KEY=A,B,...``, key paths."""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable
from typing import Any

from multilayer.case.files import MAX_DEPTH, path_text, toml_depth
from multilayer.plugin.problems import (
    MISSING,
    CaseError,
    Problem,
)

_STEP = re.compile(r"([A-Za-z0-9_-]+)((?:\[\d+\])*)$")


def parse_value(text: str) -> Any:
    """A ``--set`` value: a TOML value when it is one, else the bare string.

    Text nested deeper than :data:`~multilayer.case.files.MAX_DEPTH` is not
    parsed (the parser would recurse out of the stack): it stays a string,
    which no schema takes (:func:`apply_overrides` reports it at its key).

    >>> parse_value("5e-5"), parse_value("true"), parse_value("koiter-shell"), parse_value('"a b"')
    (5e-05, True, 'koiter-shell', 'a b')
    >>> parse_value("[" * 500 + "]" * 500)[:3]
    '[[['
    """
    if too_deep(text):
        return text.strip()
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        pass
    try:
        return float(text)
    except ValueError:
        return text.strip()


def too_deep(text: str) -> bool:
    """True when the TOML value ``text`` nests arrays or inline tables more than :data:`MAX_DEPTH` deep."""
    return toml_depth(text, stop=MAX_DEPTH) > MAX_DEPTH


def depth_problem(key: str, text: str, option: str = "--set") -> Problem | None:
    """A problem at ``key`` when a value given with ``option`` is nested too deeply, else None."""
    if not too_deep(text):
        return None
    return Problem(key, text.strip(), f"nested more than {MAX_DEPTH} levels deep (arrays, inline tables); "
                                      f"expected at most {MAX_DEPTH} (from {option})")


def key_steps(key: str) -> list[str | int] | None:
    """The steps of a dotted key path, or None when it is not one.

    >>> key_steps("layers[1].young")
    ['layers', 1, 'young']
    """
    steps: list[str | int] = []
    for part in key.split("."):
        match = _STEP.match(part)
        if not match:
            return None
        steps.append(match.group(1))
        steps.extend(int(i) for i in re.findall(r"\[(\d+)\]", match.group(2)))
    return steps


def apply_overrides(data: dict[str, Any], overrides: Iterable[str]) -> list[Problem]:
    """Apply ``key=value`` overrides to ``data`` in place; the problems found.

    A missing table on the way is created (the validator then judges its
    keys); a list index must exist.

    >>> data = {"time": {"dt": 1e-4}, "layers": [{"model": "wave-membrane"}]}
    >>> apply_overrides(data, ["time.dt=5e-5", "layers[0].tension=2e4"])
    []
    >>> data["time"]["dt"], data["layers"][0]["tension"]
    (5e-05, 20000.0)
    >>> print(*apply_overrides(data, ["layers[3].young=1"]))
    layers[3]: no such entry; 'layers' has 1
    """
    problems = []
    for item in overrides:
        key, eq, text = item.partition("=")
        key = key.strip()
        steps = key_steps(key) if eq else None
        if not steps:
            problems.append(Problem("--set", item, "expected KEY=VALUE with KEY like time.dt or layers[0].young"))
            continue
        if len(steps) > MAX_DEPTH:
            problems.append(Problem(key[:60] + "...", MISSING, f"a key path of {len(steps)} steps; expected at most "
                                                               f"{MAX_DEPTH} (from --set)"))
            continue
        deep = depth_problem(key, text)
        if deep is not None:
            problems.append(deep)
            continue
        node: Any = data
        for i, step in enumerate(steps):
            last = i == len(steps) - 1
            where = path_text(steps[: i + 1])
            if isinstance(step, int):
                if not isinstance(node, list):
                    problems.append(Problem(path_text(steps[:i]), MISSING, "not a list; cannot index it"))
                    break
                if step >= len(node):
                    problems.append(Problem(where, MISSING, f"no such entry; {path_text(steps[:i])!r} has {len(node)}"))
                    break
            elif not isinstance(node, dict):
                problems.append(Problem(path_text(steps[:i]), node, f"not a table; cannot set {step!r} in it"))
                break
            if last:
                node[step] = parse_value(text)
            else:
                if isinstance(step, str) and step not in node:
                    node[step] = {}
                node = node[step]
    return problems


def _blame_overrides(problems: list[Problem], overrides: list[str]) -> list[Problem]:
    keys = [o.partition("=")[0].strip() for o in overrides]
    out = []
    for p in problems:
        if any(p.path == k or p.path.startswith((k + ".", k + "[")) for k in keys):
            if p.hint:
                p = Problem(p.path, p.value, p.expected, f"{p.hint} (from --set)")
            else:
                p = Problem(p.path, p.value, f"{p.expected} (from --set)")
        out.append(p)
    return out


def split_values(text: str) -> list[str]:
    """Split ``text`` on the commas outside braces, brackets and TOML strings.

    >>> split_values('2e4, 8e4')
    ['2e4', '8e4']
    >>> split_values('{model="a",x=[1,2]},"b,c"')
    ['{model="a",x=[1,2]}', '"b,c"']
    >>> split_values('{model="a"')
    Traceback (most recent call last):
    ...
    ValueError: unbalanced '{': no closing '}'
    """
    closing = {"{": "}", "[": "]"}
    values, stack, quote, start, i = [], [], "", 0, 0
    while i < len(text):
        c = text[i]
        if quote:
            if c == "\\" and quote == '"':
                i += 1  # an escaped character cannot end the string
            elif c == quote:
                quote = ""
        elif c in "\"'":
            quote = c
        elif c in closing:
            stack.append(c)
        elif c in "}]":
            if not stack or closing[stack[-1]] != c:
                raise ValueError(f"unbalanced {c!r} at character {i + 1}")
            stack.pop()
        elif c == "," and not stack:
            values.append(text[start:i].strip())
            start = i + 1
        i += 1
    if quote:
        raise ValueError(f"unterminated string: no closing {quote}")
    if stack:
        raise ValueError(f"unbalanced {stack[-1]!r}: no closing {closing[stack[-1]]!r}")
    values.append(text[start:].strip())
    return values


def parse_vary(text: str) -> tuple[str, list[str]]:
    """``KEY=A,B,...`` → (KEY, [A, B, ...]); CaseError at ``--vary`` when malformed.

    >>> parse_vary("layers[0].tension=2e4,8e4")
    ('layers[0].tension', ['2e4', '8e4'])
    >>> parse_vary("tension")
    Traceback (most recent call last):
    ...
    multilayer.plugin.problems.CaseError: --vary = 'tension': expected KEY=A,B[,C...] with KEY like time.dt or layers[0].young
    """
    key, eq, rest = text.partition("=")
    key = key.strip()
    if not eq or not key_steps(key):
        raise CaseError([Problem("--vary", text, "expected KEY=A,B[,C...] with KEY like time.dt or layers[0].young")])
    try:
        values = split_values(rest)
    except ValueError as exc:
        raise CaseError([Problem("--vary", text, f"cannot split the values: {exc}")]) from None
    if any(not v for v in values):
        raise CaseError([Problem("--vary", text, "an empty value", "two commas in a row, or one at an end?")])
    if len(values) < 2:
        raise CaseError([Problem("--vary", text, "expected two or more values, separated by commas")])
    if len(key_steps(key)) > MAX_DEPTH:
        raise CaseError([Problem("--vary", text, f"a key path of {len(key_steps(key))} steps; expected at most "
                                                 f"{MAX_DEPTH}")])
    deep = [p for p in (depth_problem(key, v, "--vary") for v in values) if p is not None]
    if deep:
        raise CaseError(deep)
    return key, values
