"""Nothing lost: checkpoints and resume, interruptions, a folder held by one run, a full disk, the figures."""

import errno
import json
import os
import signal
import socket
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from runs import CASES, run_cli

import multilayer.results.folder
from multilayer.case.casefile import load_case
from multilayer.commands.common import TERMINATED
from multilayer.commands.main import main
from multilayer.results.folder import ResultsFolder, _append_to_collection, _pvd
from multilayer.runner import checkpoint
from multilayer.runner.loop import resume_run, run_case

#: a checkpoint keeps every reusing solver's held state (the matrix of its factors, its counters, its guess
#: span), so a run with checkpoints, and one resumed from them, are bit-identical to one without
SMALL = ["mesh.nz=12", "mesh.nr=3", "output.every=10"]
COUPLERS = ['{model="kinematic-splitting",scheme="crank-nicolson",beta=1}', '{model="monolithic",scheme="bdf2"}',
            '{model="dirichlet-neumann-implicit",reuse=4}']


def argv(out, *sets, case="pulse-koiter-thick", extra=()):
    a = ["run", str(CASES / f"{case}.toml"), "--out", str(out), "--quiet", "--no-plots", *extra]
    for s in (*SMALL, *sets):
        a += ["--set", s]
    return a


def same_files(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.iterdir() if p.suffix in (".csv", ".vtu", ".pvd"))
    assert names == sorted(p.name for p in b.iterdir() if p.suffix in (".csv", ".vtu", ".pvd"))
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.mark.parametrize("coupler, factors", [*((c, "double") for c in COUPLERS), (COUPLERS[0], "single")])
def test_a_run_resumed_from_its_checkpoint_is_bit_identical(tmp_path, coupler, factors):
    """100 steps at once, and 50 + resume to the same end: same series, η table, snapshots and collections."""
    full, half = tmp_path / "full", tmp_path / "half"
    sets = ("time.end=0.01", f"coupler={coupler}", f"solver.factors={factors}")
    assert main(argv(full, *sets, extra=["--checkpoint-every", "25"])) == 0
    assert main(argv(half, *sets[1:], "time.end=0.005", extra=["--checkpoint-every", "25"])) == 0
    assert main(["resume", str(half), "--until", "0.01", "--quiet", "--no-plots"]) == 0
    same_files(full, half)
    summary = json.loads((half / "summary.json").read_text())
    assert summary["steps"] == 100 and summary["resumed_from"] == 50 and summary["status"] == "ok"


def test_a_krylov_run_without_checkpoints_is_bit_identical_to_a_resumed_one(tmp_path):
    """The held solver state is checkpointed and restored: a run without checkpoints and one stopped at step 50
    and resumed write the same bytes."""
    sets = ("mesh.nz=12", "mesh.nr=3", "solver.reuse=krylov")
    _, _, full = run_cli("pulse-koiter-thick", tmp_path / "full", *sets, "time.end=0.01")
    assert main(argv(tmp_path / "half", "time.end=0.005", "solver.reuse=krylov", extra=["--checkpoint-every", "25"])) == 0
    assert main(["resume", str(tmp_path / "half"), "--until", "0.01", "--quiet", "--no-plots"]) == 0
    assert len(full) == 100
    for name in ("series.csv", "eta_lumen.csv"):
        assert (tmp_path / "half" / name).read_bytes() == (tmp_path / "full" / name).read_bytes(), name


@pytest.mark.parametrize("coupler, factors", [(COUPLERS[0], "double"), (COUPLERS[1], "double"),
                                              (COUPLERS[0], "single"), (COUPLERS[1], "single")])
def test_checkpoints_and_interruptions_do_not_perturb_a_krylov_run(tmp_path, coupler, factors):
    """Without checkpoints; with one every 7 steps; and interrupted at steps 17 and 58 (a checkpoint written
    there only), resumed each time: the same bytes of series.csv and eta_lumen.csv."""
    case = load_case(CASES / "pulse-koiter-thick.toml",
                     [*SMALL, "time.end=0.01", f"coupler={coupler}", "solver.reuse=krylov", f"solver.factors={factors}"])
    reference = tmp_path / "none"
    assert run_case(case, reference).status == "ok"

    def interrupt_at(n):
        def progress(tally, row):
            if tally.steps == n:
                os.kill(os.getpid(), signal.SIGINT)
        return progress

    every, cut = tmp_path / "every", tmp_path / "cut"
    assert run_case(case, every, checkpoint_every=7).status == "ok"
    assert run_case(case, cut, checkpoint_every=1000, progress=interrupt_at(17)).status == "interrupted"
    assert resume_run(cut, progress=interrupt_at(58)).status == "interrupted"
    assert resume_run(cut).status == "ok"
    assert json.loads((cut / "summary.json").read_text())["resumed_from"] == 58
    for name in ("series.csv", "eta_lumen.csv"):
        expected = (reference / name).read_bytes()
        assert (every / name).read_bytes() == expected, name
        assert (cut / name).read_bytes() == expected, name


def test_sigint_stops_cleanly_with_a_checkpoint_and_resume_finishes_the_run(tmp_path):
    # direct solves (Krylov reuse: test_checkpoints_and_interruptions_do_not_perturb_a_krylov_run)
    case = load_case(CASES / "pulse-koiter-thick.toml", [*SMALL, "time.end=0.01", "solver.reuse=none"])
    full, cut = tmp_path / "full", tmp_path / "cut"
    run_case(case, full)

    def interrupt_at_step_30(tally, row):
        if tally.steps == 30:
            os.kill(os.getpid(), signal.SIGINT)  # as Ctrl-C would: the step is finished, then the run stops

    result = run_case(case, cut, checkpoint_every=1000, progress=interrupt_at_step_30)
    assert result.status == "interrupted" and result.steps == 30
    summary = json.loads((cut / "summary.json").read_text())
    assert summary["status"] == "interrupted" and "SIGINT after step 30" in summary["reason"]
    assert (cut / "checkpoint.json").is_file() and (cut / "checkpoint.npz").is_file()  # written when interrupted,
    # though the cadence is 1000
    files = [d.get("file") for d in ET.parse(cut / "wall.pvd").getroot().iter("DataSet")]
    assert files == sorted(p.name for p in cut.glob("wall_*.vtu"))  # the collection lists exactly the files
    assert main(["resume", str(cut), "--quiet", "--no-plots"]) == 0
    same_files(full, cut)


def test_sigterm_from_the_cli_says_where_the_results_are(tmp_path, monkeypatch, capsys):
    from multilayer.runner import progress

    class Killer(progress.ProgressBar):
        def __call__(self, tally, row):
            if tally.steps == 3:
                os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(progress, "ProgressBar", Killer)
    out = tmp_path / "term"
    a = argv(out, "time.end=0.001")
    a.remove("--quiet")
    assert main([*a, "--checkpoint-every", "2"]) == TERMINATED
    captured = capsys.readouterr()
    text = captured.out
    assert "interrupted: 3 steps" in text and f"results in {out}" in text and f"multilayer resume {out}" in text
    assert captured.err.strip() == (f"run: interrupted by SIGTERM after step 3 (t = 0.0003 s); the results so far "
                                    f"are in {out}, continue with: multilayer resume {out}")


def test_resume_refuses_what_it_cannot_continue(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(argv(out, "time.end=0.001")) == 0
    assert main(["resume", str(out)]) == 2
    assert "no checkpoint.json" in capsys.readouterr().err
    assert main(argv(out, "time.end=0.001", extra=["--checkpoint-every", "5"])) == 0
    assert main(["resume", str(out), "--until", "0.0005"]) == 2
    assert "is not after the checkpoint's t" in capsys.readouterr().err
    good = json.loads((out / "checkpoint.json").read_text())

    def rewrite(change):  # a consistent checkpoint (its digest recomputed) that says something else
        document = json.loads(json.dumps(good))
        change(document)
        with np.load(out / "checkpoint.npz", allow_pickle=False) as npz:
            document["sha256"] = checkpoint.digest(document, {k: npz[k] for k in npz.files})
        (out / "checkpoint.json").write_text(json.dumps(document))

    rewrite(lambda d: d["plugins"]["dict"].update(coupler="kinematic-splitting somewhere 9.9"))
    assert main(["resume", str(out), "--until", "0.002"]) == 2
    assert "plugins differ" in capsys.readouterr().err
    rewrite(lambda d: d.update(case_digest="0" * 64))  # the case no longer resolves to what the checkpoint recorded
    assert main(["resume", str(out)]) == 2
    assert "resolves differently" in capsys.readouterr().err
    (out / "checkpoint.json").write_bytes(b"not a checkpoint")
    assert main(["resume", str(out)]) == 2
    assert "cannot be read" in capsys.readouterr().err


def test_a_folder_held_by_a_live_run_is_refused(tmp_path, capsys):
    out = tmp_path / "held"
    out.mkdir()
    (out / ".lock").write_text(f"{os.getppid()}\n")  # a live process that is not us
    assert main(argv(out, "time.end=0.001")) == 2
    assert "in use by another run" in capsys.readouterr().err
    (out / ".lock").write_text("999999999\n")  # a dead run's lock is taken over
    assert main(argv(out, "time.end=0.001")) == 0
    assert not (out / ".lock").exists()  # released at the end


def test_an_unusable_folder_is_refused_before_any_work(tmp_path, capsys):
    assert main(argv(Path("/proc/multilayer-cannot-be-here"), "time.end=0.001")) == 2
    assert "cannot create the results folder" in capsys.readouterr().err


def test_summary_is_written_when_the_disk_is_full(tmp_path, monkeypatch):
    real = multilayer.results.files.write_atomically

    def full_disk(path, text):
        if path.name == "summary.json":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, text)

    monkeypatch.setattr(multilayer.results.folder, "write_atomically", full_disk)
    out = tmp_path / "full"
    assert main(argv(out, "time.end=0.001")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] == 10


def test_a_snapshot_rewrites_only_the_end_of_its_collection(tmp_path):
    path, entries = tmp_path / "w.pvd", []
    for i in range(300):
        entries.append((i * 1e-4, f"w_{i:06d}.vtu"))
        before = path.stat().st_size if path.exists() else 0
        _append_to_collection(path, entries)
        if i > 0:  # one line more, whatever the number of entries
            assert path.stat().st_size - before == len(_pvd(entries[-1:])) - len(_pvd([]))
    assert path.read_text() == _pvd(entries)
    assert [d.get("timestep") for d in ET.parse(path).getroot().iter("DataSet")][:3] == ["0.0", "0.0001", "0.0002"]


def test_a_run_draws_its_figures_and_plot_redraws_them(tmp_path, capsys):
    out = tmp_path / "fig"
    a = argv(out, "time.end=0.002")
    a.remove("--no-plots")
    assert main(a) == 0
    for name in ("eta_spacetime.png", "probes.png", "energy.png"):
        assert (out / name).stat().st_size > 1000
        (out / name).unlink()
    assert main(["plot", str(out)]) == 0
    assert all((out / name).is_file() for name in ("eta_spacetime.png", "probes.png", "energy.png"))
    assert main(["plot", str(tmp_path)]) == 2
    assert "not a results folder" in capsys.readouterr().err


def test_results_folder_api_keeps_its_contract(tmp_path):
    folder = ResultsFolder(tmp_path / "x")
    assert (tmp_path / "x" / ".lock").read_text().split() == [str(os.getpid()), socket.gethostname()]
    assert json.loads((tmp_path / "x" / "summary.json").read_text())["status"] == "running"
    folder.release()


def test_series_has_its_header_before_the_first_step(tmp_path):
    out = tmp_path / "first"
    a = argv(out, "time.end=0.001", case="pulse-koiter")
    a += ["--set", 'coupler={model="dirichlet-neumann-implicit",acceleration="aitken",max_iterations=2}',
          "--set", "layers[0].density=0.05"]
    assert main(a) == 1  # fails in its first step
    assert json.loads((out / "summary.json").read_text())["steps"] == 0
    header = (out / "series.csv").read_text().splitlines()
    assert len(header) == 1 and header[0].startswith("step,t,kinetic.layers[0],") and "eta_z1" in header[0]
