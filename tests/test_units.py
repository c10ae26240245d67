"""Units a clinician types and reads (multilayer/plugin/units.py, multilayer/results/readouts.py): values with
their unit converted to CGS by pint, a wrong dimension refused in one line, an implausible plain number noted,
pressures shown in mmHg and a tube's flow rates in mL/s."""

import json
from pathlib import Path

import pytest

import multilayer as ml
from multilayer.commands.main import main
from multilayer.plugin.problems import CaseError
from multilayer.plugin.units import MMHG

CASES = Path(__file__).parents[1] / "cases"
CAROTID = CASES / "carotid.toml"


def test_values_with_units_are_read_in_cgs():
    case = ml.load_case(CAROTID, {
        "initial.pressure": "80 mmHg",                      # 80 × 1333.22 dyn/cm²
        "layers[1].young": "400 kPa",                       # 4e6 dyn/cm²
        "layers[0].thickness": "50 µm", "layers[2].thickness": "0.3 mm",
        "geometry.radius": "3 mm", "fluid.density": "1060 kg/m^3", "fluid.viscosity": "3.5 cP",
        "loads.inlet": {"model": "flow-rate", "flow": "6 mL/s"},
        "loads.outlet": {"model": "windkessel", "proximal": "1.8 mmHg*s/mL", "capacitance": "0.04 mL/mmHg",
                         "distal": "11 mmHg s/mL", "initial_pressure": "67.4 mmHg"},
        "time.dt": "1 ms"})
    r = case.resolved
    assert r["initial"]["pressure"] == pytest.approx(80 * MMHG, rel=1e-14)
    assert r["layers"][1]["young"] == 4e6 and r["layers"][0]["thickness"] == 0.005
    assert r["layers"][2]["thickness"] == 0.03 and r["geometry"]["radius"] == 0.3
    assert r["fluid"]["density"] == 1.06 and r["fluid"]["viscosity"] == 0.035
    assert r["loads"]["inlet"]["flow"] == {"model": "constant", "value": 6.0}  # 1 mL = 1 cm³
    outlet = r["loads"]["outlet"]
    assert outlet["proximal"] == pytest.approx(1.8 * MMHG, rel=1e-14)
    assert outlet["capacitance"] == pytest.approx(0.04 / MMHG, rel=1e-14)
    assert outlet["initial_pressure"] == pytest.approx(67.4 * MMHG, rel=1e-14)
    assert case.time.dt == 1e-3 and not case.warnings
    plain = ml.load_case(CAROTID, {"initial.pressure": 80 * MMHG, "layers[1].young": 4e6})
    assert plain.resolved["layers"][1] == r["layers"][1]  # the same case as the same numbers in CGS


@pytest.mark.parametrize("key, value, message", [
    ("geometry.radius", "80 mmHg", "geometry.radius = '80 mmHg': 80 mmHg is a pressure; expected a length (cm), "
                                   "like '0.3 cm'"),
    ("layers[1].young", "4 cm", "layers[1].young = '4 cm': 4 cm is a length; expected a pressure (dyn/cm²), "
                                "like '80 mmHg'"),
    ("loads.inlet.flow", "80 mmHg", "loads.inlet.flow = '80 mmHg': 80 mmHg is a pressure; expected a flow rate per "
                                    "unit depth (cm²/s) or a flow rate (cm³/s), like '6 mL/s'"),
    ("initial.pressure", "6 mL/s", "initial.pressure = '6 mL/s': 6 mL/s is a flow rate; expected a pressure "
                                   "(dyn/cm²), like '80 mmHg'"),
    ("fluid.density", "1.06 g", "fluid.density = '1.06 g': 1.06 g is a mass; expected a density (g/cm³), "
                                "like '1.06 g/cm^3'"),
    ("layers[0].thickness", "50 blorbs", "layers[0].thickness = '50 blorbs': 'blorbs' is no unit pint knows"),
])
def test_a_value_of_the_wrong_dimension_is_refused_in_one_line(key, value, message):
    with pytest.raises(CaseError) as caught:
        ml.load_case(CAROTID, {key: value})
    (line,) = str(caught.value).splitlines()
    assert line.startswith(message), line


def test_a_unit_out_of_its_bounds_is_refused_with_its_cgs_value():
    with pytest.raises(CaseError, match=r"layers\[1\]\.young = '-4 kPa': expected a number > 0.0 \(dyn/cm²\); "
                                        r"-4 kPa = -40000 dyn/cm²"):
        ml.load_case(CAROTID, {"layers[1].young": "-4 kPa"})


def test_an_implausible_plain_number_is_noted_with_its_likely_unit(capsys, tmp_path):
    case = ml.load_case(CASES / "pulse-artery-3layer.toml", {"layers[1].young": 400.0, "fluid.density": 1060})
    assert case.warnings == (
        "fluid.density = 1060: did you mean 1060 kg/m³ = 1.06 g/cm³? (a plain number is read in g/cm³)",
        "layers[1].young = 400.0: did you mean 400 kPa = 4e+06 dyn/cm²? (a plain number is read in dyn/cm²)")
    assert main(["validate", str(CAROTID), "--set", "fluid.density=1060"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: fluid.density = 1060: did you mean 1060 kg/m³ = 1.06 g/cm³?") == 1
    assert not ml.load_case(CAROTID).warnings  # the bundled case is plausible throughout


def test_pressures_are_read_in_mmhg_and_a_tubes_flow_rates_in_ml_per_s(capsys, tmp_path):
    out = tmp_path / "run"
    code = main(["run", str(CAROTID), "--out", str(out), "--no-plots", "--set", "time.end=0.01",
                 "--set", "mesh.nz=12", "--set", "mesh.nr=2"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    ranges = summary["probe_ranges"]
    p = ranges["p_mid"]
    assert (p["unit"], p["min_mmHg"], p["max_mmHg"]) == ("dyn/cm²", p["min"] / MMHG, p["max"] / MMHG)
    assert 70 < p["min_mmHg"] < p["max_mmHg"] < 90  # started at 75 mmHg
    q = ranges["q_in"]
    assert q["unit"] == "cm³/s" and (q["min_mL_s"], q["max_mL_s"]) == (q["min"], q["max"])
    assert ranges["eta_z3"]["unit"] == "cm" and "min_mmHg" not in ranges["eta_z3"]
    printed = capsys.readouterr().out
    assert f"p_mid {p['min_mmHg']:.4g} to {p['max_mmHg']:.4g} mmHg ({p['min']:.4g} to {p['max']:.4g} dyn/cm²)" \
        in printed
    assert f"q_in {q['min']:.4g} to {q['max']:.4g} mL/s" in printed
