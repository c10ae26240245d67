"""The figures as a talk shows them (multilayer/results/figures.py, the compare's probes): a unit on every axis,
pressures in mmHg (dyn/cm² on the right), titles inside the figure, fonts legible on a slide."""

import re
from pathlib import Path

import numpy as np
import pytest

import multilayer as ml
from multilayer.campaign.report import plot_compared_probes
from multilayer.plugin.units import MMHG
from multilayer.results.figures import SLIDE, plot_energy, plot_probes, plot_spacetime
from multilayer.results.reading import lumen_eta, read_run

CASES = Path(__file__).parents[1] / "cases"
UNIT = re.compile(r"\S.* \([^()]+\)$")  # "η (µm)", "p (mmHg)", "t (s)"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The composite pulse in a tube, coarse and short: η, flow-rate and pressure probes, a folder."""
    out = tmp_path_factory.mktemp("tube")
    case = ml.load_case(CASES / "pulse-koiter-thick-axisymmetric.toml",
                        {"mesh.nz": 12, "mesh.nr": 2, "mesh.order": 1, "time.end": 0.002, "output.every": 4})
    assert ml.run(case, out).ok
    return read_run("tube", out)


def labelled_axes(fig):
    """Every axis a reader sees a scale on, with its label: the y axes (secondary ones and colour bars too),
    and the x axes that show their ticks."""
    fig.canvas.draw()
    for ax in fig.axes:
        for child in [ax, *ax.child_axes]:
            if child.yaxis.get_visible() and any(t.get_text() for t in child.get_yticklabels()):
                yield child.get_ylabel()
            if child.xaxis.get_visible() and any(t.get_text() for t in child.get_xticklabels()):
                yield child.get_xlabel()


def assert_talk_ready(fig):
    labels = list(labelled_axes(fig))
    assert labels and all(UNIT.match(label) for label in labels), labels
    renderer, box = fig.canvas.get_renderer(), fig.bbox
    for ax in fig.axes:
        for text in (ax.title, *ax.texts):
            if text.get_text():
                extent = text.get_window_extent(renderer)
                assert box.x0 - 1 <= extent.x0 and extent.x1 <= box.x1 + 1, f"cut: {text.get_text()!r}"
                assert text.get_fontsize() >= SLIDE["legend.fontsize"]
        for tick in ax.get_yticklabels():
            assert tick.get_fontsize() >= SLIDE["ytick.labelsize"]
    if fig._suptitle is not None:
        extent = fig._suptitle.get_window_extent(renderer)
        assert box.x0 - 1 <= extent.x0 and extent.x1 <= box.x1 + 1


def test_the_runs_figures_have_a_unit_on_every_axis_and_titles_that_fit(run, tmp_path):
    probes = plot_probes(run, tmp_path / "probes.png")
    assert_talk_ready(probes)
    ylabels = [ax.get_ylabel() for ax in probes.axes]
    assert ylabels == ["η (µm)", "Q (mL/s)", "p (mmHg)"]
    pressure = probes.axes[2]
    assert [c.get_ylabel() for c in pressure.child_axes] == ["p (dyn/cm²)"]
    line = pressure.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), run.series[line.get_label().split()[0]] / MMHG, rtol=1e-15)
    assert_talk_ready(plot_energy(run, tmp_path / "energy.png"))
    long_title = "A title as long as a case's, naming every layer of the wall: intima | media | lamina | adventitia"
    field = lumen_eta(run.folder, 0.5)
    assert_talk_ready(plot_spacetime({"tube": field}, tmp_path / "eta.png", title=long_title))


def test_the_compare_figures_have_a_unit_on_every_axis(run, tmp_path):
    other = read_run("again", run.folder)
    assert_talk_ready(plot_compared_probes([run, other], tmp_path / "probes.png"))
    fields = {r.label: lumen_eta(r.folder, 0.5) for r in (run, other)}
    assert_talk_ready(plot_spacetime(fields, tmp_path / "eta.png", title="two variants"))
