import csv
import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from multilayer.results.folder import ResultsError, ResultsFolder


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_series_rows_are_on_disk_as_soon_as_appended(tmp_path):
    out = ResultsFolder(tmp_path / "a" / "b")
    series = out.series(["step", "t", "eta"])
    assert read_rows(out.path / "series.csv") == []  # the header alone
    values = [0.1, 1 / 3, np.float64(2e-17)]
    for step, eta in enumerate(values, start=1):
        series.append({"step": step, "t": step * 1e-4, "eta": eta})
        rows = read_rows(out.path / "series.csv")  # no close needed
        assert len(rows) == step
    assert [float(r["eta"]) for r in rows] == [float(v) for v in values]  # shortest repr round-trips exactly
    assert [int(r["step"]) for r in rows] == [1, 2, 3]


def test_series_missing_column_is_empty_and_unknown_is_an_error(tmp_path):
    series = ResultsFolder(tmp_path).series(["t", "p"])
    series.append({"t": 1.0})
    assert read_rows(tmp_path / "series.csv") == [{"t": "1.0", "p": ""}]
    with pytest.raises(KeyError, match="pp"):
        series.append({"t": 2.0, "pp": 1.0})


def square():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    return points, {"triangle": np.array([[0, 1, 2], [1, 3, 2]])}


def pvd_entries(path):
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def test_snapshots_are_readable_and_collected(tmp_path):
    out = ResultsFolder(tmp_path)
    points, cells = square()
    times = [0.0, 1e-3, 2.5e-3]
    for step, t in enumerate(times):
        disp = np.column_stack([np.zeros(4), np.full(4, t)])
        out.snapshot("wall", points, cells, {"displacement": disp, "p": np.arange(4.0) * step}, t=t, step=step * 10)
        # the collection is valid after every snapshot
        assert pvd_entries(tmp_path / "wall.pvd") == [(times[i], f"wall_{i * 10:06d}.vtu") for i in range(step + 1)]
    mesh = meshio.read(tmp_path / "wall_000020.vtu")
    assert mesh.points.shape == (4, 3)
    assert mesh.cells_dict["triangle"].tolist() == [[0, 1, 2], [1, 3, 2]]
    assert mesh.point_data["displacement"].shape == (4, 3)  # padded: ParaView sees a vector
    np.testing.assert_allclose(mesh.point_data["displacement"][:, 1], 2.5e-3)
    np.testing.assert_allclose(mesh.point_data["p"], np.arange(4.0) * 2)


def test_line_snapshots_and_separate_collections(tmp_path):
    out = ResultsFolder(tmp_path)
    points = np.column_stack([np.linspace(0, 6, 4), np.full(4, 0.5), np.zeros(4)])
    out.snapshot("line", points, {"line": np.array([[0, 1], [1, 2], [2, 3]])}, {"eta": np.ones(4)}, t=0.5, step=3)
    out.snapshot("wall", *square(), t=0.5, step=3)
    assert meshio.read(tmp_path / "line_000003.vtu").cells_dict["line"].shape == (3, 2)
    assert pvd_entries(tmp_path / "line.pvd") == [(0.5, "line_000003.vtu")]
    assert pvd_entries(tmp_path / "wall.pvd") == [(0.5, "wall_000003.vtu")]


def test_summary_converts_numpy(tmp_path):
    out = ResultsFolder(tmp_path)
    path = out.write_summary({"status": "ok", "steps": np.int64(3), "max": np.float32(0.5),
                              "eta": np.array([1.0, 2.0]), "where": tmp_path})
    data = json.loads(path.read_text())
    assert data == {"status": "ok", "steps": 3, "max": 0.5, "eta": [1.0, 2.0], "where": str(tmp_path)}
    assert path.read_text().startswith('{\n  "status"')  # indent 2


def test_snapshots_of_every_wall_have_the_same_fields_and_the_fluid_is_not_moved_twice(tmp_path):
    from runs import CASES

    from multilayer.commands.main import main

    fields = {}
    for case in ("pulse-koiter", "pulse-koiter-thick"):
        out = tmp_path / case
        argv = ["run", str(CASES / f"{case}.toml"), "--out", str(out), "--quiet", "--no-plots"]
        for s in ("mesh.nz=6", "mesh.nr=2", "time.end=2e-4", "output.every=1"):
            argv += ["--set", s]
        assert main(argv) == 0
        wall = meshio.read(out / "wall_000002.vtu")
        fields[case] = sorted(wall.point_data)
        assert all(v.shape[1] == 3 for v in wall.point_data.values())
        fluid = meshio.read(out / "fluid_000002.vtu")
        assert sorted(fluid.point_data) == ["pressure", "velocity"]  # the points are already deformed
    assert fields["pulse-koiter"] == fields["pulse-koiter-thick"] == ["displacement", "velocity"]


def test_the_manifest_lists_each_snapshot_before_it_is_written_and_is_rewritten_rarely(tmp_path, monkeypatch):
    out = ResultsFolder(tmp_path / "m")
    writes = []
    real = ResultsFolder._write_manifest
    monkeypatch.setattr(ResultsFolder, "_write_manifest", lambda self: (writes.append(1), real(self))[1])
    points, cells = square()
    steps = range(0, 3000, 10)
    for step in steps:
        out.snapshot("wall", points, cells, t=step * 1e-4, step=step)
        assert f"wall_{step:06d}.vtu" in json.loads((out.path / "manifest.json").read_text())["files"]
    assert len(writes) <= 12  # O(log n) rewrites: the next snapshots are claimed ahead
    out.release()  # the ones claimed ahead and not written are dropped
    listed = {f for f in json.loads((out.path / "manifest.json").read_text())["files"] if f.endswith(".vtu")}
    assert listed == {f"wall_{s:06d}.vtu" for s in steps} == {p.name for p in out.path.glob("*.vtu")}


def test_a_snapshot_never_overwrites_a_file_the_run_did_not_write(tmp_path):
    (tmp_path / "line_000030.vtu").write_bytes(b"mine")
    out = ResultsFolder(tmp_path, force=True)  # not a results folder: --force
    points, cells = square()
    for step in (0, 10, 20):
        out.snapshot("line", points, cells, step=step)
    with pytest.raises(ResultsError, match="line_000030.vtu was not written by this run"):
        out.snapshot("line", points, cells, step=30)
    assert (tmp_path / "line_000030.vtu").read_bytes() == b"mine"
    out.release()
