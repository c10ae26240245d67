"""Every coupler in a tube (theory §11): the ledger closes, restarts are bit-identical, the tube is stiffer.

The composite pulse in a tube is bundled (cases/pulse-koiter-thick-axisymmetric.toml),
so tests/test_coupled.py already runs it with every coupler and checks its
ledger every step; here the thin-walled pulses in a tube, with every
coupler, and what the tube changes.  Measured: ledger ≤ 9.9e-13 relative
over these 14 runs and the 7 coarse runs of the bundled composite tube.
"""

import numpy as np
import pytest
from runs import assert_resume_is_bit_identical, run_cli
from test_coupled import (
    COARSE,
    LEDGER,
    SECOND_ORDER,
    _eta_series,
    _orders,
    volume_margin,
)

TUBE = 'geometry.model="axisymmetric"'
COMPOSITE_TUBE = "pulse-koiter-thick-axisymmetric"


def columns(rows):
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("coupler", LEDGER)
@pytest.mark.parametrize("case", ["pulse-koiter", "pulse-membrane"])
def test_thin_walled_tube_ledger_closes_every_step(case, coupler, tmp_path):
    code, summary, rows = run_cli(case, tmp_path / case, TUBE, *COARSE, f"coupler={LEDGER[coupler]}",
                                  *volume_margin(coupler))
    s = columns(rows)
    assert code == 0 and summary["status"] == "ok" and len(s["t"]) == 20
    assert np.all(s["energy.relative_residual"] <= 1e-9)
    assert np.max(np.abs(s["eta_z1"])) > 0 and np.max(s["q_in"]) > 0


def test_the_composite_tube_moves_less_than_the_channel(tmp_path):
    """The bundled tube against the same scene in the planar channel, monolithic Crank–Nicolson (coarser, to 6 ms).

    In a tube the band has its hoop stiffness (theory §11): the lumen moves
    far less than in the channel, where the band mostly translates (measured
    peak η at z = 1: 226 µm in the tube, 517 µm in the channel, nz = 30, nr = 4).
    """
    sets = ("mesh.nz=30", "mesh.nr=4", "time.end=0.006", 'coupler={model="monolithic",scheme="crank-nicolson"}')
    peaks = {}
    for case in ("pulse-koiter-thick-axisymmetric", "pulse-koiter-thick"):
        code, summary, rows = run_cli(case, tmp_path / case, *sets)
        assert code == 0 and summary["energy"]["max_relative_residual"] <= 1e-9
        peaks[case] = np.max(np.abs(columns(rows)["eta_z1"]))
    assert peaks["pulse-koiter-thick-axisymmetric"] < 0.6 * peaks["pulse-koiter-thick"]


def test_a_tube_resumes_bit_identically(tmp_path):
    assert_resume_is_bit_identical(tmp_path, "pulse-koiter-thick-axisymmetric", "mesh.nz=12", "mesh.nr=3",
                                   'coupler={model="monolithic",scheme="bdf2"}')


@pytest.fixture(scope="module")
def tube_reference(tmp_path_factory):
    """Monolithic Crank–Nicolson at Δt = 3.125e-6 on the composite tube (20 × 4 cells, to 4 ms), as in planar."""
    return _eta_series(COMPOSITE_TUBE, tmp_path_factory.mktemp("tube-ref"), "monolithic-cn", 3.125e-6)


@pytest.mark.slow
@pytest.mark.parametrize("coupler", SECOND_ORDER)
def test_second_order_couplers_are_second_order_in_a_tube(coupler, tube_reference, tmp_path):
    """Relative L∞ errors of η at z = 1, 2 against the reference, Δt = 1e-4, 5e-5, 2.5e-5. Measured:

    splitting-cn    0.583 0.202 0.0552 → 1.53 1.87
    monolithic-cn   0.104 0.0250 0.00611 → 2.06 2.03
    monolithic-bdf2 0.361 0.103 0.0255 → 1.81 2.01

    The tube is stiffer than the channel (its band has hoop stiffness): the
    pulse is shorter in time and the asymptotic range starts at a smaller Δt.
    """
    errors, orders = _orders(COMPOSITE_TUBE, tube_reference, coupler, (1e-4, 5e-5, 2.5e-5), tmp_path)
    assert orders[-1] >= 1.8, (errors, orders)


@pytest.mark.slow
@pytest.mark.parametrize("coupler, low", [("splitting", 0.65), ("splitting-beta", 0.8), ("monolithic-be", 0.85)])
def test_first_order_couplers_are_first_order_in_a_tube(coupler, low, tube_reference, tmp_path):
    """The same, Δt = 5e-5 … 6.25e-6. Measured:

    splitting       0.695 0.525 0.356 0.215 → 0.40 0.56 0.73
    splitting-beta  0.590 0.429 0.256 0.140 → 0.46 0.74 0.88
    monolithic-be   0.906 0.519 0.280 0.146 → 0.80 0.89 0.94

    First order with a large constant, approached from below as in the channel.
    """
    errors, orders = _orders(COMPOSITE_TUBE, tube_reference, coupler, (2.5e-5, 1.25e-5, 6.25e-6), tmp_path)
    assert np.all(np.diff(errors) < 0)
    assert low < orders[-1] < 1.3, (errors, orders)
