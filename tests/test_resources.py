"""What a case needs against what the machine has: exact unknowns, the memory estimate, its inputs."""

import pytest

from multilayer.case import resources
from multilayer.case.resources import available_memory, fluid_dofs, need, wall_dofs
from multilayer.wall.stack import WallSpace
from multilayer_plugins.channel.channel import Channel
from multilayer_plugins.linear_elastic import LinearElasticBand
from multilayer_plugins.planar import Planar
from multilayer_plugins.thin_shell import KoiterFamilyLayer


@pytest.mark.parametrize("nz, nr", [(3, 2), (7, 5), (12, 1)])
@pytest.mark.parametrize("order", [1, 2])
def test_fluid_unknowns_are_those_of_the_channel(nz, nr, order):
    channel = Channel.build(Planar(), 6.0, 0.5, nz, nr, order)
    assert fluid_dofs(nz, nr, order) == channel.velocity.N + channel.pressure.N


@pytest.mark.parametrize("nz", [3, 8])
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("cells", [[], [3], [3, 2]])
def test_wall_unknowns_are_those_of_the_wall(nz, order, cells):
    thin = KoiterFamilyLayer(1.0, 0.1, C1=1.0)
    layers = [thin] + [LinearElasticBand(1.0, 0.1, 1.0, 1.0) for _ in cells]
    space = WallSpace.build(layers, Planar(), 6.0, 0.5, nz, order, [None, *cells])
    assert wall_dofs(nz, order, cells) == space.ndofs


# Peak resident memory of the runs of `python scripts/memory_per_dof.py` (docs/case-files.md, Size limits).
MEASURED = [  # (mesh, order, fluid dofs + wall dofs, peak MB: the larger of kinematic-splitting and monolithic)
    ((60, 8), 2, 6841, 145.1),
    ((120, 16), 2, 22301, 290.5),
    ((240, 32), 2, 79141, 847.2),
    ((480, 64), 2, 296501, 2891.8),
    ((960, 128), 2, 1145941, 9095.3),  # kinematic-splitting, benchmarks/scaling.py (docs/performance.md, run C)
    ((60, 8), 1, 4177, 119.1),
    ((240, 32), 1, 56989, 464.7),
]


@pytest.mark.parametrize("mesh, order, dofs, peak_mb", MEASURED)
def test_the_estimate_lies_above_every_measured_run(mesh, order, dofs, peak_mb):
    needed = need(*mesh, order, fluid=True, wall=True, band_cells=[4])  # pulse-koiter-thick
    assert needed.dofs == dofs
    assert peak_mb * 1e6 <= needed.memory <= 3 * peak_mb * 1e6


def test_the_estimate_per_unknown_grows_beyond_the_measured_runs():
    """Flat up to 300k unknowns, then like N^GROWTH (measured from 297k to 1.15M unknowns)."""
    def per_dof(n):
        return (n.memory - resources.BASELINE) / n.dofs
    small, measured, large = need(60, 8, 2, True, True), need(480, 64, 2, True, True), need(1920, 256, 2, True, True)
    assert per_dof(small) == per_dof(measured) == resources.BYTES_PER_DOF
    assert per_dof(large) / per_dof(measured) == pytest.approx((large.dofs / 300_000) ** resources.GROWTH)
    assert per_dof(large) > per_dof(measured)


def test_available_memory_reads_meminfo(tmp_path):
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       32000000 kB\nMemFree:         1000000 kB\nMemAvailable:   24000000 kB\n")
    assert available_memory(meminfo) == 24000000 * 1024.0
    assert available_memory() is None or available_memory() > 0  # this machine


def test_available_memory_without_meminfo_falls_back(tmp_path, monkeypatch):
    monkeypatch.setattr(resources.os, "sysconf", lambda name: {"SC_AVPHYS_PAGES": 1000, "SC_PAGE_SIZE": 4096}[name])
    assert available_memory(tmp_path / "missing") == 4096000.0
