import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from multilayer.functions.formula import Formula, FormulaError


@pytest.mark.parametrize(
    "expr, words",
    [
        ("__import__('os')", "'__import__'"),
        ("__import__('os').system('true')", "attribute access"),
        ("z.real", "attribute access"),
        ("(lambda: 1)()", "lambda"),
        ("lambda z: z", "lambda"),
        ("[1, 2][0]", "subscript"),
        ("z if r else t", "where("),
        ("z and r", "'and'"),
        ("'text'", "not a number"),
        ("True", "not a number"),
        ("z // 2", "not allowed"),
        ("sin", "call it"),
        ("z(1)", "not a function"),
        ("sin(z, 1)", "takes 1 argument"),
        ("sqrt(x=z)", "keyword"),
        ("open('f')", "unknown name 'open'"),
        ("1 +", "not a valid expression"),
        ("sinn(z)", "did you mean 'sin'?"),
        ("zz + 1", "did you mean 'z'?"),
    ],
)
def test_rejects_anything_but_arithmetic(expr, words):
    with pytest.raises(FormulaError) as info:
        Formula.parse(expr)
    assert words in str(info.value)


def test_unknown_name_suggests_a_constant():
    with pytest.raises(FormulaError, match="unknown name 'Lx'; did you mean 'L'"):
        Formula.parse("Lx * z", constants={"L": 6.0, "R": 0.5})


def test_variables_can_be_restricted():
    with pytest.raises(FormulaError, match="unknown name 'z'"):
        Formula.parse("sin(z)", variables=("t",))
    assert float(Formula.parse("2*t", variables=("t",))(t=1.5)) == 3.0


def test_constants_and_builtin_names():
    f = Formula.parse("A*sin(pi*z/L) + e", constants={"A": 2.0, "L": 6.0})
    assert float(f(z=3.0)) == pytest.approx(2.0 + np.e)


def test_broadcasts_to_the_shape_of_the_variables():
    f = Formula.parse("z*t")
    out = f(z=np.arange(3.0)[:, None], t=np.arange(4.0)[None, :])
    assert out.shape == (3, 4) and out.dtype == float
    assert out[2, 3] == 6.0


@pytest.mark.parametrize("expr", ["0", "1.5", "pi", "L"])
def test_a_constant_formula_still_broadcasts(expr):
    out = Formula.parse(expr, constants={"L": 6.0})(z=np.zeros(5), r=np.zeros((2, 1)))
    assert out.shape == (2, 5) and out.dtype == float
    assert np.all(out == out.flat[0])


def test_scalar_inputs_give_a_0d_float_array():
    out = Formula.parse("z + 1")(z=2)
    assert isinstance(out, np.ndarray) and out.shape == () and float(out) == 3.0


def test_comparisons_give_floats_elementwise_even_chained():
    t = np.array([-1.0, 0.5, 2.0])
    assert Formula.parse("(t > 0) * 3")(t=t).tolist() == [0.0, 3.0, 3.0]
    assert Formula.parse("0 < t < 1")(t=t).tolist() == [0.0, 1.0, 0.0]


def test_numpy_functions():
    z = np.array([-2.0, 0.5, 3.0])
    assert Formula.parse("where(z > 0, sqrt(abs(z)), 0)")(z=z).tolist() == [0.0, np.sqrt(0.5), np.sqrt(3.0)]
    assert Formula.parse("minimum(z, 1) + maximum(z, 0)")(z=z).tolist() == [-2.0, 1.0, 4.0]
    assert float(Formula.parse("log(exp(2)) + tanh(0) + cosh(0) - sinh(0) + tan(0)")()) == 3.0


def test_zero_text_equality_and_pickling():
    f = Formula.parse("0.01*sin(pi*z/L)", {"L": 6.0})
    assert str(f) == "0.01*sin(pi*z/L)"
    assert f == Formula.parse("0.01*sin(pi*z/L)", {"L": 6.0})
    assert f != Formula.parse("0.01*sin(pi*z/L)", {"L": 5.0})
    g = pickle.loads(pickle.dumps(f))
    assert g == f and float(g(z=3.0)) == pytest.approx(0.01)
    assert Formula.zero()(z=[1.0, 2.0]).tolist() == [0.0, 0.0]


def test_a_number_is_its_own_formula():
    assert float(Formula.parse(2.5)()) == 2.5
    with pytest.raises(FormulaError):
        Formula.parse(True)


@given(
    a=st.floats(-1e6, 1e6, allow_nan=False),
    b=st.floats(-1e6, 1e6, allow_nan=False),
    z=st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=5),
)
def test_linear_formula_matches_numpy(a, b, z):
    f = Formula.parse(f"{a!r}*z + {b!r}")
    np.testing.assert_allclose(f(z=z), a * np.array(z) + b, rtol=1e-12, atol=1e-9)


# -- limits: a formula is bounded before Python's parser sees it ------------------

@pytest.mark.parametrize(
    "expr, words",
    [
        ("z+" * 50_000 + "z", "too long: 100001 characters; expected at most 2000"),
        ("(" * 150 + "z" + ")" * 150, "nested too deeply: 150 levels of brackets; expected at most 100"),
        ("sin(" * 120 + "z" + ")" * 120, "nested too deeply: 120 levels of brackets"),
        ("-" * 500 + "z", "nested too deeply: 501 levels"),
        ("z" + "+z" * 150, "nested too deeply: 151 levels (each operator of a chain"),
        ("z**2000", "the exponent 2000 is too large; expected a number of magnitude at most 1000"),
        ("z**-5000", "the exponent -5000 is too large"),
        ("1e400*z", "the number 1e400 is too large for a float"),
        ("1" + "0" * 400, "is too large for a float"),
    ],
)
def test_refuses_what_is_too_big_to_parse_or_evaluate(expr, words):
    with pytest.raises(FormulaError) as info:
        Formula.parse(expr)
    assert words in str(info.value)


def test_the_largest_accepted_formula_parses():
    chain = "z" + "+z" * 98  # 99 operators: a tree 100 levels deep
    assert float(Formula.parse(chain)(z=1.0)) == 99.0
    assert float(Formula.parse("(" * 99 + "z" + ")" * 99)(z=2.0)) == 2.0
    assert float(Formula.parse("z**1000")(z=1.0)) == 1.0


@pytest.mark.filterwarnings("ignore:overflow encountered")
def test_numbers_are_floats_never_python_integers():
    # as Python integers these take hours and gigabytes; as floats they overflow at once
    assert np.isinf(Formula.parse("9**9**9")())
    assert np.isinf(Formula.parse("10**10**10*t")(t=1.0))
    # float arithmetic, not exact integer arithmetic
    assert float(Formula.parse("(10**16 + 1) - 10**16")()) == 0.0
    assert float(Formula.parse("2**64")()) == 2.0**64


@pytest.mark.filterwarnings("ignore:divide by zero")
def test_division_by_zero_gives_inf_not_an_exception():
    assert np.isinf(Formula.parse("1/0")())
    assert np.isinf(Formula.parse("L/H", constants={"L": 6.0, "H": 0.0})())
