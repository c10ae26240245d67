import hashlib
import math

import numpy as np
import pytest
from scipy.integrate import quad

from multilayer.functions.formula import Formula
from multilayer.functions.loads import (
    ConstantPressure,
    CosinePulse,
    FormulaPressure,
    SinePressure,
    TablePressure,
    load_from_spec,
)
from multilayer.functions.tablefile import read_table
from multilayer.plugin.problems import CaseError


def quad_average(load, t0, t1, breaks=()):
    inside = [b for b in breaks if t0 < b < t1]
    value, _ = quad(lambda t: float(load.value(t)), t0, t1, points=inside or None, limit=500,
                    epsabs=1e-13, epsrel=1e-13)
    return value / (t1 - t0)


def steps(t0, t1, dt):
    n = int(round((t1 - t0) / dt))
    return [(t0 + i * dt, t0 + (i + 1) * dt) for i in range(n)]


PULSE = CosinePulse(amplitude=1.3333e4, duration=0.003)
TABLE = TablePressure([0.0, 0.1, 0.25, 0.4], [0.0, 1.0e4, -2.0e3, 5.0e2], scale=1.5)
PERIODIC = TablePressure([0.05, 0.2, 0.5, 0.7], [1.0, 4.0, -2.0, 3.0], period=0.8)


@pytest.mark.parametrize(
    "load, windows, breaks",
    [
        (ConstantPressure(2.5), steps(0.0, 1.0, 0.3), ()),
        # steps of 0.0007 s straddle the end of the pulse at 0.003 s, and t = 0
        (PULSE, steps(-0.0014, 0.0056, 0.0007), (0.0, 0.003)),
        (SinePressure(amplitude=3.0, frequency=7.0, mean=1.0, phase=0.4), steps(0.0, 0.5, 0.037), ()),
        # steps straddle breakpoints, and run before the first and after the last time
        (TABLE, steps(-0.07, 0.6, 0.045), tuple(TABLE.times)),
        # steps cross the wrap of the cycle at t0 + period = 0.85 and 1.65
        (PERIODIC, steps(0.0, 2.4, 0.13), tuple(np.concatenate([PERIODIC.times + k * 0.8 for k in range(-1, 4)]))
         + tuple(0.05 + k * 0.8 for k in range(4))),
    ],
    ids=["constant", "cosine-pulse", "sine", "table", "table-periodic"],
)
def test_average_is_the_exact_time_average(load, windows, breaks):
    for t0, t1 in windows:
        exact = quad_average(load, t0, t1, breaks)
        assert load.average(t0, t1) == pytest.approx(exact, rel=1e-11, abs=1e-9 * (1 + abs(exact)))


def test_formula_average_uses_five_point_gauss():
    load = FormulaPressure(Formula.parse("1e4*exp(-((t - 0.01)/0.003)**2)", variables=("t",)))
    for t0, t1 in steps(0.0, 0.02, 1e-4):
        assert load.average(t0, t1) == pytest.approx(quad_average(load, t0, t1), rel=1e-10, abs=1e-9)
    poly = FormulaPressure(Formula.parse("t**9 - 3*t**4", variables=("t",)))
    assert poly.average(0.0, 2.0) == pytest.approx((2.0**10 / 10 - 3 * 2.0**5 / 5) / 2.0, rel=1e-13)


def test_pulse_values_and_its_average_over_the_whole_pulse():
    assert float(PULSE.value(0.0015)) == pytest.approx(1.3333e4)
    assert float(PULSE.value(0.004)) == 0.0 and float(PULSE.value(-1.0)) == 0.0
    assert PULSE.average(0.0, 0.003) == pytest.approx(1.3333e4 / 2)
    assert PULSE.average(0.003, 0.01) == 0.0


def test_zero_length_step_gives_the_value():
    assert SinePressure(amplitude=1.0, frequency=1.0).average(0.25, 0.25) == pytest.approx(1.0)


def test_table_holds_end_values_and_repeats_with_a_period():
    assert float(TABLE.value(-1.0)) == 0.0 and float(TABLE.value(9.0)) == pytest.approx(750.0)
    assert float(PERIODIC.value(0.05 + 0.8 * 3 + 0.15)) == pytest.approx(4.0)
    # the cycle closes linearly from (0.7, 3) to (0.85, 1)
    assert float(PERIODIC.value(0.775)) == pytest.approx(2.0)
    assert PERIODIC.average(0.05, 0.85) == pytest.approx(PERIODIC.average(0.85, 1.65), rel=1e-12)


def test_table_longer_than_its_period_is_refused():
    with pytest.raises(ValueError, match="more than one period"):
        TablePressure([0.0, 1.0], [0.0, 1.0], period=0.5)


@pytest.mark.parametrize("header", ["", "t,p\n", "time (s), pressure (dyn/cm2)\n", "# measured\nt, p\n"])
def test_csv_with_or_without_header(tmp_path, header):
    path = tmp_path / "p.csv"
    path.write_text(header + "0, 0\n0.1,10\n\n0.2, 5 # peak passed\n")
    t, p = read_table(path)
    assert t.tolist() == [0.0, 0.1, 0.2] and p.tolist() == [0.0, 10.0, 5.0]


def test_csv_whitespace_separated(tmp_path):
    path = tmp_path / "p.dat"
    path.write_text("0 1\n1 2\n")
    assert read_table(path)[1].tolist() == [1.0, 2.0]


@pytest.mark.parametrize(
    "text, words",
    [
        ("t,p\n0,1\n0.1,x\n", "line 3"),
        ("0,1\n0.1,2,3\n", "line 2"),
        ("0,1\n", "at least two rows"),
        ("0,1\n0,2\n", "increase strictly"),
        ("0,1\n1,nan\n", "finite"),
    ],
)
def test_bad_csv_names_the_problem(tmp_path, text, words):
    path = tmp_path / "p.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=words):
        read_table(path)


def test_load_from_spec_every_kind(tmp_path):
    (tmp_path / "inlet.csv").write_text("t,p\n0,0\n0.5,100\n1,0\n")
    specs = [
        (7, 7.0),
        ("2*t + L", 2 * 0.25 + 6.0),
        ({"model": "constant", "value": 3}, 3.0),
        ({"model": "cosine-pulse", "amplitude": 2.0, "duration": 1.0}, 1.0),
        ({"model": "sine", "amplitude": 1.0, "frequency": 1.0}, 2.0 / np.pi),
        ({"model": "table", "file": "inlet.csv", "scale": 2.0}, 100.0),
        ({"model": "formula", "expr": "4*t"}, 1.0),
    ]
    for spec, avg in specs:
        load = load_from_spec(spec, "loads.inlet", tmp_path, {"L": 6.0})
        assert load.average(0.0, 0.5) == pytest.approx(avg), spec
        again = load_from_spec(load.to_dict(), "loads.inlet", tmp_path, {"L": 6.0})
        assert again.average(0.1, 0.4) == pytest.approx(load.average(0.1, 0.4)), spec


def test_table_is_relative_to_the_case_folder_and_pinned_by_its_hash(tmp_path):
    data = b"0,1\n1,3\n"
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "p.csv").write_bytes(data)
    load = load_from_spec({"model": "table", "file": "data/p.csv"}, "loads.outlet", tmp_path)
    assert load.to_dict() == {"model": "table", "file": "data/p.csv", "period": None, "scale": 1.0,
                              "sha256": hashlib.sha256(data).hexdigest()}
    with pytest.raises(CaseError, match=r"loads.outlet.sha256 = '0+': the file's SHA-256 differs"):
        load_from_spec({"model": "table", "file": "data/p.csv", "sha256": "0" * 64}, "loads.outlet", tmp_path)


@pytest.mark.parametrize(
    "spec, message",
    [
        (True, "loads.inlet = true: expected a number, a formula in t or a table"),
        ([1, 2], "loads.inlet = [1, 2]: expected a number"),
        (float("inf"), "expected a finite pressure"),
        ("sin(z)", "loads.inlet = 'sin(z)': invalid formula in t: unknown name 'z'"),
        ({"amplitude": 1.0}, "loads.inlet.model: missing"),
        ({"model": "pulse"}, "loads.inlet.model = 'pulse': no such pressure load; did you mean 'cosine-pulse'?"),
        ({"model": "cosine-pulse", "amplitude": 1.0}, "loads.inlet.duration: missing; expected a number > 0.0 (s)"),
        ({"model": "cosine-pulse", "amplitude": 1.0, "duration": 0}, "loads.inlet.duration = 0: expected a number > 0.0"),
        ({"model": "sine", "amplitude": 1.0, "frequency": 1.0, "phse": 0.0},
         "loads.inlet.phse = 0.0: unknown key; did you mean 'phase'?"),
        ({"model": "table", "file": "missing.csv"}, "loads.inlet.file = 'missing.csv': no such file"),
        ({"model": "formula", "expr": "t +"}, "loads.inlet.expr = 't +': invalid formula"),
    ],
)
def test_bad_specs_raise_case_errors_with_the_key_path(tmp_path, spec, message):
    with pytest.raises(CaseError) as info:
        load_from_spec(spec, "loads.inlet", tmp_path)
    assert message in str(info.value)


def test_bad_table_file_is_a_case_error(tmp_path):
    (tmp_path / "p.csv").write_text("0,1\n0.5,oops\n")
    with pytest.raises(CaseError, match=r"loads.inlet.file = 'p.csv': invalid table: line 2"):
        load_from_spec({"model": "table", "file": "p.csv"}, "loads.inlet", tmp_path)


@pytest.mark.parametrize("period,dt", [(0.8, 1e-3), (0.02, 3e-5), (0.6, 0.07)])
def test_periodic_table_averages_across_many_cycle_boundaries(period, dt):
    # floor and mod taken apart disagree by a whole cycle at some boundaries in floating point;
    # every step average of a table must lie between its extremes and match quadrature
    table = TablePressure(np.array([0.0, 0.3 * period, period]), np.array([80.0, 120.0, 80.0]), period=period)
    steps = int(round(6 * period / dt)) + 3
    averages = np.array([table.average(n * dt, (n + 1) * dt) for n in range(steps)])
    assert averages.min() >= 80.0 - 1e-9 and averages.max() <= 120.0 + 1e-9
    for n in range(0, steps, max(1, steps // 40)):
        exact = quad(table.value, n * dt, (n + 1) * dt, limit=200)[0] / dt
        assert averages[n] == pytest.approx(exact, rel=1e-9, abs=1e-9)


def smooth_table(rows, **kwargs):
    """A periodic cubic table of P = sin(2πt) + cos(4πt)/2 sampled at ``rows`` points of the period 1."""
    t = np.arange(rows) / rows
    return TablePressure(t, np.sin(2 * np.pi * t) + 0.5 * np.cos(4 * np.pi * t), period=1.0,
                         interpolation="cubic", **kwargs)


def test_a_periodic_cubic_table_converges_at_fourth_order_and_its_averages_are_its_integrals():
    """Halving the rows divides the error of the spline by 2⁴ (measured 16.6 and 16.2 from 20 to 80 rows); the
    step averages are the spline's exact integrals (against adaptive quadrature of its values), and P' is
    continuous across a period's end (the periodic spline; 6.28286 and 6.28282 either side), where the
    linear table's slope jumps (4.27 and 8.09)."""
    exact = lambda t: np.sin(2 * np.pi * t) + 0.5 * np.cos(4 * np.pi * t)  # noqa: E731
    fine = np.linspace(0.0, 3.0, 3001)
    errors = [float(np.max(np.abs(smooth_table(n).value(fine) - exact(fine)))) for n in (20, 40, 80)]
    assert 15.0 < errors[0] / errors[1] < 17.5 and 15.0 < errors[1] / errors[2] < 17.0
    load = smooth_table(20)
    for t0, t1 in [(0.0, 0.37), (0.93, 1.21), (0.5, 2.75), (-0.3, 0.1)]:
        rows = tuple(np.arange(-20, 60) / 20)  # the spline's knots: quad integrates piece by piece
        assert load.average(t0, t1) == pytest.approx(quad_average(load, t0, t1, rows), rel=1e-11, abs=1e-12)
    assert load.average(0.0, 3.0) == pytest.approx(0.0, abs=1e-13)
    slope = lambda p, t, h=1e-7: (float(p.value(t + h)) - float(p.value(t - h))) / (2 * h)  # noqa: E731
    assert abs(slope(load, 1.0 - 2e-7) - slope(load, 1.0 + 2e-7)) < 1e-3 * abs(slope(load, 1.0))


def test_a_cubic_table_without_a_period_holds_its_end_values_and_its_breakpoints_are_its_ends():
    load = TablePressure(np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.0, 1.0, 4.0, 9.0]), interpolation="cubic")
    assert load.value(1.5) == pytest.approx(2.25)  # not-a-knot: the quadratic through the rows, exactly
    assert float(load.value(-1.0)) == 0.0 and float(load.value(5.0)) == 9.0
    assert load.average(2.0, 4.0) == pytest.approx(quad_average(load, 2.0, 4.0, (3.0,)), rel=1e-12)
    assert [load.next_breakpoint(t) for t in (-1.0, 0.0, 1.5, 3.0)] == [0.0, 3.0, 3.0, math.inf]


def test_a_linear_tables_breakpoints_are_its_rows_every_period():
    load = TablePressure(np.array([0.0, 0.1, 0.3]), np.array([1.0, 2.0, 0.0]), period=0.4)
    points = [0.0]
    for _ in range(7):
        points.append(load.next_breakpoint(points[-1]))
    assert points == pytest.approx([0.0, 0.1, 0.3, 0.4, 0.5, 0.7, 0.8, 0.9], abs=1e-15)
    assert load.next_breakpoint(0.1 + 1e-17) == pytest.approx(0.3)  # round-off after a landing: the next one
    once = TablePressure(np.array([0.0, 0.1]), np.array([1.0, 2.0]))
    assert [once.next_breakpoint(t) for t in (-0.5, 0.05, 0.1)] == [0.0, 0.1, math.inf]
    assert SinePressure(1.0, 4.0).cycle() == 0.25 and SinePressure(1.0, 4.0).next_breakpoint(0.1) == math.inf


@pytest.mark.parametrize("spec, words", [
    ({"interpolation": "spline"}, "loads.inlet.interpolation = 'spline': expected one of 'linear', 'cubic'"),
    ({"interpolation": "cubic", "period": 1.0}, "must end on its first value"),
])
def test_bad_interpolations_are_refused_with_their_key_path(tmp_path, spec, words):
    (tmp_path / "p.csv").write_text("0,1\n0.5,3\n1,2\n")
    with pytest.raises(CaseError, match=words):
        load_from_spec({"model": "table", "file": "p.csv", **spec}, "loads.inlet", tmp_path)
