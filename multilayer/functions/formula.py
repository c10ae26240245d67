"""Safe arithmetic formulas of (z, r, t), as a case file writes them.

A formula is parsed with :mod:`ast` and checked against a whitelist before it
is compiled: numbers, ``+ - * / **``, unary minus, comparisons (which give
1.0 or 0.0), calls of a few numpy functions, the names ``pi`` and ``e``, the
variables and the constants the caller names (``L``, ``R``, ``H``).  Nothing
else — no attributes, subscripts, lambdas or builtins — gets through, so a
case file can never run code.

A formula is also bounded before Python's parser sees it: at most
:data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` levels of nesting, so a
huge or deeply nested text is refused with a message instead of a
``MemoryError`` or ``RecursionError``.  Every number is evaluated as a
float64 (never as a Python integer, so ``9**9**9`` overflows to ``inf`` at
once instead of computing a 370-million-digit integer), and a number written
as an exponent is at most :data:`MAX_EXPONENT` in magnitude.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Iterable, Mapping
from types import CodeType

import attrs
import numpy as np

from multilayer.plugin.registry import nearest

VARIABLES = ("z", "r", "t")

#: Callable functions and how many arguments each takes.
FUNCTIONS = {
    "sin": (np.sin, 1),
    "cos": (np.cos, 1),
    "tan": (np.tan, 1),
    "exp": (np.exp, 1),
    "log": (np.log, 1),
    "sqrt": (np.sqrt, 1),
    "tanh": (np.tanh, 1),
    "sinh": (np.sinh, 1),
    "cosh": (np.cosh, 1),
    "abs": (np.abs, 1),
    "minimum": (np.minimum, 2),
    "maximum": (np.maximum, 2),
    "where": (np.where, 3),
}

BUILTIN_CONSTANTS = {"pi": math.pi, "e": math.e}

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNARY = (ast.USub, ast.UAdd)
_COMPARE = (ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.Eq, ast.NotEq)
#: name of the helper that turns a comparison into 1.0/0.0; users cannot write it
_AS_FLOAT = "__as_float__"
#: names of the float64 numbers of a compiled formula (users cannot write a name starting with "_")
_NUMBER = "__n{}__"

#: Longest formula text, in characters (a long series belongs in a table load).
MAX_LENGTH = 2000
#: Deepest nesting: brackets, and the levels of the expression tree (each operator of a chain is a level).
MAX_DEPTH = 100
#: Largest magnitude of a number written as an exponent (``z**2`` yes, ``10**400`` no).
MAX_EXPONENT = 1000.0


class FormulaError(ValueError):
    """A formula that is not valid arithmetic of the allowed names."""


def _described(node: ast.AST) -> str:
    kinds = {
        ast.Attribute: "attribute access",
        ast.Subscript: "a subscript",
        ast.Lambda: "lambda",
        ast.BoolOp: "'and'/'or' (multiply comparisons instead)",
        ast.IfExp: "'if ... else' (use where(cond, a, b))",
        ast.Starred: "'*' unpacking",
    }
    for kind, text in kinds.items():
        if isinstance(node, kind):
            return text
    return type(node).__name__


class _Checker(ast.NodeVisitor):
    def __init__(self, names: Iterable[str], source: str = ""):
        self.names = set(names)
        self.source = source

    def fail(self, message: str) -> None:
        raise FormulaError(message)

    def unknown(self, name: str) -> None:
        if name.startswith("_"):
            self.fail(f"name {name!r} is not allowed in a formula")
        hint = nearest(name, sorted(self.names | set(FUNCTIONS)))
        self.fail(f"unknown name {name!r}" + (f"; did you mean {hint!r}?" if hint else ""))

    def visit_Expression(self, node: ast.Expression) -> None:
        self.visit(node.body)

    def visit_Constant(self, node: ast.Constant) -> None:
        if isinstance(node.value, bool) or not isinstance(node.value, int | float):
            self.fail(f"{node.value!r} is not a number")
        if not math.isfinite(_literal(node)):
            written = ast.get_source_segment(self.source, node) or str(node.value)
            self.fail(f"the number {_short(written)} is too large for a float (at most about 1.8e308)")

    def visit_Name(self, node: ast.Name) -> None:
        if node.id in FUNCTIONS:
            self.fail(f"{node.id!r} is a function; call it as {node.id}(...)")
        if node.id not in self.names:
            self.unknown(node.id)

    def visit_BinOp(self, node: ast.BinOp) -> None:
        if type(node.op) not in _BINOPS:
            self.fail(f"operator {type(node.op).__name__} is not allowed; use + - * / **")
        self.visit(node.left)
        self.visit(node.right)
        exponent = _literal(node.right) if isinstance(node.op, ast.Pow) else None
        if exponent is not None and abs(exponent) > MAX_EXPONENT:
            self.fail(f"the exponent {exponent:g} is too large; expected a number of magnitude at most "
                      f"{MAX_EXPONENT:g} (write exp(...) for exponential growth)")

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        if not isinstance(node.op, _UNARY):
            self.fail(f"operator {type(node.op).__name__} is not allowed")
        self.visit(node.operand)

    def visit_Compare(self, node: ast.Compare) -> None:
        if not all(isinstance(op, _COMPARE) for op in node.ops):
            self.fail("only < <= > >= == != comparisons are allowed")
        self.visit(node.left)
        for c in node.comparators:
            self.visit(c)

    def visit_Call(self, node: ast.Call) -> None:
        if not isinstance(node.func, ast.Name):
            self.fail(f"{_described(node.func)} is not allowed in a formula")
        name = node.func.id
        if name not in FUNCTIONS:
            if name in self.names:
                self.fail(f"{name!r} is not a function")
            self.unknown(name)
        if node.keywords:
            self.fail("keyword arguments are not allowed in a formula")
        nargs = FUNCTIONS[name][1]
        if len(node.args) != nargs:
            self.fail(f"{name}() takes {nargs} argument{'s' if nargs > 1 else ''}, got {len(node.args)}")
        for a in node.args:
            self.visit(a)

    def generic_visit(self, node: ast.AST) -> None:
        self.fail(f"{_described(node)} is not allowed in a formula")


class _FloatComparisons(ast.NodeTransformer):
    """``a < b < c`` → ``as_float(a < b) * as_float(b < c)``: element-wise on arrays."""

    def visit_Compare(self, node: ast.Compare) -> ast.AST:
        self.generic_visit(node)
        left, result = node.left, None
        for op, right in zip(node.ops, node.comparators):
            pair = ast.Call(
                func=ast.Name(_AS_FLOAT, ast.Load()),
                args=[ast.Compare(left=left, ops=[op], comparators=[right])],
                keywords=[],
            )
            result = pair if result is None else ast.BinOp(result, ast.Mult(), pair)
            left = right
        return result


class _FloatNumbers(ast.NodeTransformer):
    """Every number → the name of a float64 constant: arithmetic is never done on Python integers."""

    def __init__(self) -> None:
        self.numbers: dict[str, np.float64] = {}

    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        name = _NUMBER.format(len(self.numbers))
        self.numbers[name] = np.float64(node.value)
        return ast.copy_location(ast.Name(name, ast.Load()), node)


def _short(text: str) -> str:
    return text if len(text) <= 20 else f"{text[:8]}...{text[-4:]} ({len(text)} characters)"


def _literal(node: ast.AST) -> float | None:
    """The value of a number written with an optional sign, else None."""
    sign = 1.0
    while isinstance(node, ast.UnaryOp) and isinstance(node.op, _UNARY):
        sign = -sign if isinstance(node.op, ast.USub) else sign
        node = node.operand
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool):
        try:
            return sign * float(node.value)
        except OverflowError:
            return sign * math.inf
    return None


def bracket_depth(text: str) -> int:
    """The deepest nesting of ``()``, ``[]`` and ``{}`` in ``text`` (a scan, no parsing).

    >>> bracket_depth("sin((z + 1) * 2)"), bracket_depth("z")
    (2, 0)
    """
    depth = deepest = 0
    for char in text:
        if char in "([{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in ")]}":
            depth = max(depth - 1, 0)
    return deepest


def tree_depth(tree: ast.AST) -> int:
    """Levels of expressions in ``tree``, counted without recursion.

    >>> tree_depth(ast.parse("z + z + z", mode="eval"))
    3
    """
    deepest, stack = 0, [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, ast.expr):
            depth += 1
            deepest = max(deepest, depth)
        stack.extend((child, depth) for child in ast.iter_child_nodes(node))
    return deepest


def _bounded(expr: str) -> str:
    """``expr`` stripped, or FormulaError when it is too long or too deeply nested to parse safely."""
    text = expr.strip()
    if len(text) > MAX_LENGTH:
        raise FormulaError(f"too long: {len(text)} characters; expected at most {MAX_LENGTH} "
                           "(give a long series as a table load)")
    depth = bracket_depth(text)
    if depth > MAX_DEPTH:
        raise FormulaError(f"nested too deeply: {depth} levels of brackets; expected at most {MAX_DEPTH}")
    return text


def _compile(expr: str, names: Iterable[str]) -> tuple[CodeType, dict[str, np.float64]]:
    text = _bounded(expr)
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else ""
        raise FormulaError(f"not a valid expression{where} ({exc.msg})") from None
    except (MemoryError, RecursionError):  # pragma: no cover - the bounds above are well inside the parser's
        raise FormulaError(f"too complex to parse; expected at most {MAX_DEPTH} levels of nesting") from None
    depth = tree_depth(tree)
    if depth > MAX_DEPTH:
        raise FormulaError(f"nested too deeply: {depth} levels (each operator of a chain such as a + b + c "
                           f"counts as one); expected at most {MAX_DEPTH}")
    _Checker(names, text).visit(tree)
    numbers = _FloatNumbers()
    tree = numbers.visit(_FloatComparisons().visit(tree))
    return compile(ast.fix_missing_locations(tree), "<formula>", "eval"), numbers.numbers


def _as_float(x: object) -> np.ndarray:
    return np.asarray(x, dtype=float)


@attrs.frozen
class Formula:
    """An arithmetic expression of z, r, t and named constants, evaluated with numpy.

    Parameters
    ----------
    expr : str
        The expression, e.g. ``"0.01*sin(pi*z/L)"``.
    constants : mapping of str to float
        Named constants the expression may use besides ``pi`` and ``e``.
    variables : tuple of str
        The variables it may use (a subset of z, r, t).

    Examples
    --------
    >>> f = Formula.parse("A*sin(pi*z/L)", constants={"A": 2.0, "L": 6.0})
    >>> float(f(z=3.0))
    2.0
    >>> f(z=[0.0, 1.5, 3.0], t=0.0).round(3).tolist()
    [0.0, 1.414, 2.0]
    >>> Formula.parse("(t < 1) * 5")(t=[0.5, 2.0]).tolist()
    [5.0, 0.0]
    >>> Formula.parse("zz")
    Traceback (most recent call last):
    ...
    multilayer.functions.formula.FormulaError: unknown name 'zz'; did you mean 'z'?
    """

    expr: str = attrs.field(converter=str)
    constants: tuple[tuple[str, float], ...] = attrs.field(
        default=(), converter=lambda c: tuple(sorted((str(k), float(v)) for k, v in dict(c).items()))
    )
    variables: tuple[str, ...] = attrs.field(default=VARIABLES, converter=tuple)
    _code: tuple[CodeType, dict[str, np.float64]] = attrs.field(init=False, eq=False, repr=False)

    @variables.validator
    def _known_variables(self, attribute: attrs.Attribute, value: tuple[str, ...]) -> None:
        unknown = set(value) - set(VARIABLES)
        if unknown:
            raise ValueError(f"formula variables must be among {VARIABLES}, got {sorted(unknown)}")

    @_code.default
    def _checked_code(self) -> tuple[CodeType, dict[str, np.float64]]:
        names = set(self.variables) | set(BUILTIN_CONSTANTS) | {k for k, _ in self.constants}
        return _compile(self.expr, names)

    @classmethod
    def parse(
        cls,
        expr: str | float,
        constants: Mapping[str, float] | None = None,
        variables: Iterable[str] = VARIABLES,
    ) -> Formula:
        """Check and compile ``expr`` (a number is accepted as its own formula).

        Raises
        ------
        FormulaError
            On a syntax error or anything outside the whitelist, naming the
            offending name and the nearest valid one; on a text longer than
            :data:`MAX_LENGTH` or nested deeper than :data:`MAX_DEPTH`; on a
            number too large for a float or an exponent beyond
            :data:`MAX_EXPONENT`.
        """
        if isinstance(expr, bool) or not isinstance(expr, str | int | float):
            raise FormulaError(f"expected a formula (a string or a number), got {expr!r}")
        return cls(str(expr), constants or {}, tuple(variables))

    @classmethod
    def zero(cls) -> Formula:
        """The formula ``0``.

        >>> Formula.zero()(z=[1.0, 2.0]).tolist()
        [0.0, 0.0]
        """
        return cls("0")

    def __call__(self, z: object = 0.0, r: object = 0.0, t: object = 0.0) -> np.ndarray:
        """Evaluate; the result is a float array of the broadcast shape of z, r, t.

        Every number and name is a float64, so a division by zero or an
        overflow gives ``inf`` or ``nan`` (with numpy's warning), never a
        Python exception.
        """
        values = {"z": np.asarray(z, dtype=float), "r": np.asarray(r, dtype=float), "t": np.asarray(t, dtype=float)}
        shape = np.broadcast_shapes(*(v.shape for v in values.values()))
        code, numbers = self._code
        namespace: dict[str, object] = {name: fn for name, (fn, _) in FUNCTIONS.items()}
        namespace.update({k: np.float64(v) for k, v in BUILTIN_CONSTANTS.items()})
        namespace.update({k: np.float64(v) for k, v in self.constants})
        namespace.update(numbers)
        namespace.update(values)
        namespace[_AS_FLOAT] = _as_float
        out = eval(code, {"__builtins__": {}}, namespace)  # noqa: S307 - checked AST
        return np.array(np.broadcast_to(np.asarray(out, dtype=float), shape))

    def __str__(self) -> str:
        return self.expr

    def __reduce__(self) -> tuple:
        # the compiled code cannot be pickled; rebuild it from the text
        return (type(self), (self.expr, dict(self.constants), self.variables))
