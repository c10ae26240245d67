"""Safe arithmetic formulas of (z, r, t), as a case file writes them.

A formula is parsed with :mod:`ast` and checked against a whitelist before it
is compiled: numbers, ``+ - * / **``, unary minus, comparisons (which give
1.0 or 0.0), calls of a few numpy functions, the names ``pi`` and ``e``, the
variables and the constants the caller names (``L``, ``R``, ``H``).  Nothing
else — no attributes, subscripts, lambdas or builtins — gets through, so a
case file can never run code.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Iterable, Mapping
from types import CodeType

import attrs
import numpy as np

from multilayer.registry import nearest

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
    def __init__(self, names: Iterable[str]):
        self.names = set(names)

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


def _compile(expr: str, names: Iterable[str]) -> CodeType:
    try:
        tree = ast.parse(expr.strip(), mode="eval")
    except SyntaxError as exc:
        where = f" at column {exc.offset}" if exc.offset else ""
        raise FormulaError(f"not a valid expression{where} ({exc.msg})") from None
    _Checker(names).visit(tree)
    tree = ast.fix_missing_locations(_FloatComparisons().visit(tree))
    return compile(tree, "<formula>", "eval")


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
    multilayer.formula.FormulaError: unknown name 'zz'; did you mean 'z'?
    """

    expr: str = attrs.field(converter=str)
    constants: tuple[tuple[str, float], ...] = attrs.field(
        default=(), converter=lambda c: tuple(sorted((str(k), float(v)) for k, v in dict(c).items()))
    )
    variables: tuple[str, ...] = attrs.field(default=VARIABLES, converter=tuple)
    _code: CodeType = attrs.field(init=False, eq=False, repr=False)

    @variables.validator
    def _known_variables(self, attribute: attrs.Attribute, value: tuple[str, ...]) -> None:
        unknown = set(value) - set(VARIABLES)
        if unknown:
            raise ValueError(f"formula variables must be among {VARIABLES}, got {sorted(unknown)}")

    @_code.default
    def _checked_code(self) -> CodeType:
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
            offending name and the nearest valid one.
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
        """Evaluate; the result is a float array of the broadcast shape of z, r, t."""
        values = {"z": np.asarray(z, dtype=float), "r": np.asarray(r, dtype=float), "t": np.asarray(t, dtype=float)}
        shape = np.broadcast_shapes(*(v.shape for v in values.values()))
        namespace: dict[str, object] = {name: fn for name, (fn, _) in FUNCTIONS.items()}
        namespace.update(BUILTIN_CONSTANTS)
        namespace.update(dict(self.constants))
        namespace.update(values)
        namespace[_AS_FLOAT] = _as_float
        out = eval(self._code, {"__builtins__": {}}, namespace)  # noqa: S307 - checked AST
        return np.array(np.broadcast_to(np.asarray(out, dtype=float), shape))

    def __str__(self) -> str:
        return self.expr

    def __reduce__(self) -> tuple:
        # the compiled code cannot be pickled; rebuild it from the text
        return (type(self), (self.expr, dict(self.constants), self.variables))
