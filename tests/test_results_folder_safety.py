"""Issue 21: a results folder owns only what it wrote (its manifest), refuses a dangerous --out, and is
held by one run at a time (an atomic lock)."""

import json
import os
import re
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from multilayer.commands.main import main
from multilayer.results.folder import MANIFEST, ResultsError, ResultsFolder, owned_files

CASES = Path(__file__).parents[1] / "cases"
SMALL = ["mesh.nz=12", "mesh.nr=3", "output.every=5", "time.end=0.001"]


def argv(out, *extra, plots=False, sets=()):
    a = ["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out), "--quiet", *extra]
    if not plots:
        a.append("--no-plots")
    for s in (*SMALL, *sets):
        a += ["--set", s]
    return a


def user_files(folder: Path) -> dict[str, bytes]:
    """A user's own files: a text file, a PNG, a sub-folder with a file."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {"notes.txt": b"my notes\n", "my.png": b"\x89PNG\r\n\x1a\nnot drawn by multilayer",
             "old_wall_000001.vtu": b"a user's, not a snapshot name of a run", "sub/keep.csv": b"a,b\n1,2\n"}
    for name, data in files.items():
        (folder / name).parent.mkdir(exist_ok=True)
        (folder / name).write_bytes(data)
    return files


def unchanged(folder: Path, files: dict[str, bytes]) -> bool:
    return all((folder / name).read_bytes() == data for name, data in files.items())


# -- the manifest ---------------------------------------------------------------------------------------------
def test_a_users_files_survive_a_forced_run_a_rerun_and_a_resume(tmp_path, capsys):
    out = tmp_path / "mine"
    files = user_files(out)
    assert main(argv(out)) == 2  # not a results folder: refused without --force
    assert "not a results folder of multilayer" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["my.png", "notes.txt", "old_wall_000001.vtu", "sub"]
    assert main(argv(out, "--force", plots=True)) == 0  # the figures drawn, my.png kept
    assert unchanged(out, files)
    assert (out / "energy.png").stat().st_size > 1000
    owned = owned_files(out)
    assert {"summary.json", "series.csv", "energy.png", "wall_000010.vtu", MANIFEST} <= owned
    assert not owned & set(files)
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["format"] == "multilayer results folder" and "wall_000005.vtu" in manifest["files"]
    # now a results folder of ours: a new run needs no --force, replaces its own files and keeps the user's
    assert main(argv(out, "--checkpoint-every", "5", sets=["time.end=0.0015"], plots=True)) == 0
    assert unchanged(out, files)
    assert (out / "wall_000015.vtu").is_file()
    assert main(["resume", str(out), "--until", "0.002", "--quiet"]) == 0
    assert unchanged(out, files)
    assert json.loads((out / "summary.json").read_text())["steps"] == 20
    # a shorter run removes the snapshots of the longer one: they were its own
    assert main(argv(out)) == 0
    assert not (out / "wall_000015.vtu").exists() and (out / "wall_000010.vtu").is_file()
    assert not (out / "checkpoint.json").exists() and not (out / "checkpoint.npz").exists()
    assert unchanged(out, files)
    assert sorted(p.name for p in out.iterdir() if p.name in files or p.name == "sub") == sorted(
        ["my.png", "notes.txt", "old_wall_000001.vtu", "sub"])


def test_a_resume_drops_only_its_own_later_snapshots(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(argv(out, "--checkpoint-every", "10", sets=["time.end=0.0015"])) == 0  # checkpoint at step 10
    assert (out / "wall_000015.vtu").is_file()
    files = user_files(out)
    (out / "wall_000099.vtu").write_bytes(b"a user's file with a snapshot's name")  # not in the manifest
    assert main(["resume", str(out), "--until", "0.0012", "--quiet", "--no-plots"]) == 2  # refused, untouched
    assert "wall_000099.vtu" in capsys.readouterr().err
    assert (out / "wall_000015.vtu").is_file()
    (out / "wall_000099.vtu").unlink()
    assert main(["resume", str(out), "--until", "0.0012", "--quiet", "--no-plots"]) == 0
    assert not (out / "wall_000015.vtu").exists()  # the run's own, after its checkpoint: dropped
    assert "wall_000015.vtu" not in owned_files(out)
    assert unchanged(out, files)


def test_a_file_of_a_name_the_run_writes_that_it_did_not_write_stops_it_first(tmp_path, capsys):
    out = tmp_path / "clash"
    files = user_files(out)
    (out / "energy.png").write_bytes(b"my energy plot")
    assert main(argv(out, "--force")) == 2
    assert "energy.png" in capsys.readouterr().err
    assert (out / "energy.png").read_bytes() == b"my energy plot" and unchanged(out, files)
    assert not (out / MANIFEST).exists() and not (out / ".lock").exists()
    (out / "energy.png").unlink()
    (out / MANIFEST).write_text('{"someone": "else"}')  # a manifest.json that is not ours
    assert main(argv(out, "--force")) == 2
    assert (out / MANIFEST).read_text() == '{"someone": "else"}'


def test_plot_keeps_a_figure_file_the_run_did_not_write(tmp_path):
    out = tmp_path / "p"
    assert main(argv(out)) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"].remove("probes.png")  # as if a user had put their own probes.png there
    (out / MANIFEST).write_text(json.dumps(manifest))
    (out / "probes.png").write_bytes(b"mine")
    assert main(["plot", str(out)]) == 0
    assert (out / "probes.png").read_bytes() == b"mine"
    assert (out / "energy.png").stat().st_size > 1000


def test_a_results_folder_of_an_older_multilayer_is_reused(tmp_path):
    out = tmp_path / "old"
    assert main(argv(out, plots=True)) == 0
    (out / MANIFEST).unlink()  # as an older multilayer left it: summary.json, no manifest
    files = user_files(out)
    assert main(argv(out)) == 0
    assert unchanged(out, files) and (out / MANIFEST).is_file()


# -- a dangerous --out ------------------------------------------------------------------------------------
@pytest.mark.parametrize("where", ["", ".", "cwd-absolute", "cwd-relative"])
def test_the_current_directory_is_refused(tmp_path, monkeypatch, capsys, where):
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    (cwd / "my.png").write_bytes(b"mine")
    monkeypatch.chdir(cwd)
    out = {"": "", ".": ".", "cwd-absolute": str(cwd), "cwd-relative": "../cwd/."}[where]
    assert main(argv(out)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and ("is empty" if not out else "current directory") in err
    assert sorted(p.name for p in cwd.iterdir()) == ["my.png"]  # nothing written, nothing removed
    if out:  # --force: the run writes into it, and only its own files
        assert main(argv(out, "--force")) == 0
        assert (cwd / "my.png").read_bytes() == b"mine" and (cwd / "summary.json").is_file()


def test_root_and_home_are_refused(tmp_path, monkeypatch, capsys):
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    assert main(argv(home)) == 2
    assert "home folder" in capsys.readouterr().err
    assert main(argv("/")) == 2
    assert "root of the file system" in capsys.readouterr().err
    assert list(home.iterdir()) == []
    with pytest.raises(ResultsError, match="is empty"):
        ResultsFolder("")


# -- symbolic links -----------------------------------------------------------------------------------------
def test_links_are_never_followed(tmp_path, capsys):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    out = tmp_path / "links"
    assert main(argv(out, "--checkpoint-every", "5")) == 0
    for name in ("summary.json.tmp", ".summary.json.0123abcd.tmp", "series.csv", "summary.json",
                 "checkpoint.json", "wall_000005.vtu", "wall.pvd"):
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(outside)
    assert main(argv(out, "--checkpoint-every", "5", plots=True)) == 0
    assert outside.read_text() == "precious"
    assert (out / "summary.json.tmp").is_symlink()  # not the run's: left as it was
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    assert not (out / "series.csv").is_symlink()  # the run's own name: replaced
    # a link where the run appends: refused, not followed
    folder = ResultsFolder(tmp_path / "api")
    series = folder.series(["step"])
    series.path.unlink()
    series.path.symlink_to(outside)
    with pytest.raises(ResultsError, match="symbolic link"):
        series.append({"step": 1})
    folder.release()
    assert outside.read_text() == "precious"


def test_a_lock_that_is_a_link_is_refused_and_its_target_unchanged(tmp_path, capsys):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    out = tmp_path / "lk"
    assert main(argv(out)) == 0
    (out / ".lock").symlink_to(outside)
    assert main(argv(out)) == 2
    assert "symbolic link" in capsys.readouterr().err
    assert outside.read_text() == "precious"
    (out / ".lock").unlink()
    (out / ".lock").symlink_to(tmp_path / "nowhere")  # dangling: not created either
    assert main(argv(out)) == 2
    assert not (tmp_path / "nowhere").exists()


# -- the lock -----------------------------------------------------------------------------------------------
def test_two_openings_started_together_exactly_one_wins_200_times(tmp_path):
    """200 trials: two threads open one folder at the same instant; one holds it, the other is refused."""
    trials = 200
    for trial in range(trials):
        folder = tmp_path / f"t{trial % 20}"  # new folders, and folders earlier trials used
        start, done = threading.Barrier(2), threading.Barrier(2)
        won, lost = [], []

        def open_folder():
            start.wait()
            try:
                held = ResultsFolder(folder)
            except ResultsError as exc:
                lost.append(str(exc))
                held = None
            else:
                won.append(held)
            done.wait()  # the winner holds the folder until both have tried
            if held is not None:
                held.release()

        threads = [threading.Thread(target=open_folder) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert len(won) == 1 and len(lost) == 1, (trial, lost)
        assert "in use by another run" in lost[0] and f"PID {os.getpid()}" in lost[0]
        assert not (folder / ".lock").exists()


def hold_in_another_process(folder: Path) -> subprocess.Popen:
    code = ("import sys; from multilayer.results.folder import ResultsFolder; f = ResultsFolder(sys.argv[1]); "
            "print('held', flush=True); sys.stdin.read()")
    proc = subprocess.Popen([sys.executable, "-c", code, str(folder)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_live_holder_is_named_and_a_dead_ones_lock_is_taken_over(tmp_path, capsys):
    out = tmp_path / "held"
    proc = hold_in_another_process(out)
    try:
        assert main(argv(out)) == 2
        err = capsys.readouterr().err
        assert f"in use by another run (PID {proc.pid})" in err and len(err.strip().splitlines()) == 1
    finally:
        proc.kill()  # dies holding it: its lock file stays, its flock goes
        proc.wait()
    assert (out / ".lock").read_text().split() == [str(proc.pid), socket.gethostname()]
    assert main(argv(out)) == 0  # the stale lock is taken over
    assert not (out / ".lock").exists()
    (out / ".lock").write_text(f"{proc.pid} {socket.gethostname()}\n")  # a dead PID of this host
    assert main(argv(out)) == 0


def test_two_runs_started_together_one_runs_the_other_is_refused(tmp_path):
    """Full runs, in two processes released at the same instant (1 + 1 trials)."""
    go = tmp_path / "go"
    code = ("import os, sys, time\n"
            "from multilayer.commands.main import main\n"
            "import multilayer.runner.loop, multilayer.case.casefile\n"
            "print('ready', flush=True)\n"
            "while not os.path.exists(sys.argv[1]): time.sleep(0.0002)\n"
            "sys.exit(main(sys.argv[2:]))\n")
    for trial in range(2):
        out = tmp_path / f"both{trial}"
        go.unlink(missing_ok=True)
        runs = [subprocess.Popen([sys.executable, "-c", code, str(go), *argv(out, sets=["time.end=0.004"])],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
        assert [p.stdout.readline().strip() for p in runs] == ["ready", "ready"]
        go.touch()
        codes = [p.wait(timeout=300) for p in runs]
        errors = [p.stderr.read() for p in runs]
        assert sorted(codes) == [0, 2], errors
        assert "in use by another run" in errors[codes.index(2)]
        assert json.loads((out / "summary.json").read_text())["status"] == "ok"


CAMPAIGN = ["compare", str(CASES / "membrane-mode.toml"), "--vary", "time.dt=1e-5,2e-5", "--set", "time.end=0.0003"]


def test_a_campaign_folder_owns_only_what_it_wrote(tmp_path, capsys, monkeypatch):
    """compare (as study, stability, sweep): a foreign folder is refused, --force writes beside the user's files
    and never over them, the campaign run again rewrites its own reports, and a run and a campaign refuse
    each other's folder."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes")
    assert main([*CAMPAIGN, "--out", str(mine)]) == 2
    assert "not a campaign folder of multilayer" in capsys.readouterr().err
    (mine / "report.md").write_text("my report")
    assert main([*CAMPAIGN, "--out", str(mine), "--force"]) == 2  # a report name held by the user's file
    assert "holds report.md that no campaign of multilayer wrote" in capsys.readouterr().err
    (mine / "report.md").unlink()
    assert main([*CAMPAIGN, "--out", str(mine), "--force"]) == 0
    assert (mine / "notes.txt").read_text() == "my notes"
    owned = json.loads((mine / MANIFEST).read_text())
    assert owned["format"] == "multilayer campaign folder"
    assert owned["files"] == ["eta_spacetime.png", "probes.png", "report.json", "report.md"]
    assert main([*CAMPAIGN, "--out", str(mine)]) == 0  # its own folder now: no --force needed
    assert main(argv(mine)) == 2  # a run does not write into a campaign's folder
    assert main([*CAMPAIGN, "--out", str(mine / "dt=1e-5")]) == 2  # nor a campaign into a run's
    monkeypatch.chdir(tmp_path)
    assert main([*CAMPAIGN, "--out", "."]) == 2
    assert "is the current directory" in capsys.readouterr().err


@pytest.mark.parametrize("entry", ["../outside.txt", "ABSOLUTE", "sub", "sub/keep.csv", "notes.txt", 7])
def test_a_manifest_naming_what_a_run_never_writes_is_refused_and_nothing_is_touched(tmp_path, capsys, entry):
    """Issue 36: a manifest is data a folder carries; a crafted one (a path out of the folder, an absolute path,
    a sub-folder, a user's file, not a name at all) must not make the next run remove anything."""
    outside = tmp_path / "outside.txt"
    outside.write_bytes(b"a user's file beside the folder\n")
    out = tmp_path / "run"
    assert main(argv(out)) == 0
    files = user_files(out)
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"].append(str(outside) if entry == "ABSOLUTE" else entry)
    (out / MANIFEST).write_text(json.dumps(manifest))
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main(argv(out)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a file a run of multilayer writes in its folder" in err, err
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before  # nothing removed or written
    assert all((out / name).read_bytes() == data for name, data in files.items())


def test_a_file_of_the_run_replaced_by_a_link_is_removed_as_a_link_and_its_target_kept(tmp_path):
    out = tmp_path / "run"
    assert main(argv(out)) == 0
    target = tmp_path / "precious.csv"
    target.write_bytes(b"not the run's\n")
    (out / "series.csv").unlink()
    (out / "series.csv").symlink_to(target)
    assert main(argv(out)) == 0
    assert target.read_bytes() == b"not the run's\n" and not (out / "series.csv").is_symlink()


@pytest.mark.parametrize("entry", ["../../outside_000001.vtu", "ABSOLUTE", "fluid_000001.vtu", "link_000001.vtu"])
def test_read_results_reads_only_the_runs_own_snapshots(tmp_path, entry):
    """Issue 36: a .pvd is data; ``read_results`` follows it only to this part's snapshots inside the folder."""
    import multilayer as ml

    out = tmp_path / "run"
    assert main(argv(out)) == 0
    (out / "eta_lumen.csv").unlink()  # the snapshots are then what η(z, t) is read from
    outside = tmp_path / "outside_000001.vtu"
    outside.write_bytes((out / "wall_000005.vtu").read_bytes())
    if entry == "link_000001.vtu":
        (out / entry).symlink_to(outside)
    pvd = (out / "wall.pvd").read_text()
    first = pvd.split('file="')[1].split('"')[0]
    (out / "wall.pvd").write_text(pvd.replace(first, str(outside) if entry == "ABSOLUTE" else entry, 1))
    with pytest.raises(ResultsError, match="not a snapshot wall_<step>.vtu of the run in its folder"):
        ml.read_results(out)


@pytest.mark.parametrize("kind", ["link-loop", "long-name"])
def test_an_out_the_system_cannot_follow_or_name_ends_in_one_line(tmp_path, capsys, kind):
    if kind == "link-loop":
        out = tmp_path / "a"
        out.symlink_to(tmp_path / "b")
        (tmp_path / "b").symlink_to(out)
        words = "loop"
    else:
        out = tmp_path / ("x" * 300)
        words = "too long"
    assert main(argv(out)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot be used as a results folder" in err and words in err, err


@pytest.mark.parametrize("entry", ["../outside.txt", "ABSOLUTE", "sub/keep.csv", ".hidden.json", "notes.txt", None])
def test_a_campaign_manifest_naming_what_a_campaign_never_writes_is_refused_and_nothing_is_touched(
        tmp_path, capsys, entry):
    """Issue 36: a campaign folder's manifest is data too; only report files directly inside are taken from it."""
    outside = tmp_path / "outside.txt"
    outside.write_bytes(b"a user's file beside the folder\n")
    out = tmp_path / "campaign"
    assert main([*CAMPAIGN, "--out", str(out)]) == 0
    user_files(out)
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"].append(str(outside) if entry == "ABSOLUTE" else entry)
    (out / MANIFEST).write_text(json.dumps(manifest))
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main([*CAMPAIGN, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a report a campaign of multilayer writes" in err, err
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_a_campaigns_run_folder_that_is_a_link_or_a_report_that_is_a_folder_is_refused(tmp_path, capsys):
    """A shared campaign folder whose run folder links to another results folder would make the campaign
    rerun (and so empty) that folder; a report replaced by a folder is refused before anything is written."""
    out = tmp_path / "campaign"
    assert main([*CAMPAIGN, "--out", str(out)]) == 0
    elsewhere = tmp_path / "precious-run"
    (out / "dt=1e-5").rename(elsewhere)
    (out / "dt=1e-5").symlink_to(elsewhere)
    before = {p: p.read_bytes() for p in elsewhere.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main([*CAMPAIGN, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "dt=1e-5 is a link" in err, err
    assert {p: p.read_bytes() for p in elsewhere.rglob("*") if p.is_file()} == before
    (out / "dt=1e-5").unlink()
    (out / "report.md").unlink()
    (out / "report.md").mkdir()
    assert main([*CAMPAIGN, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "report.md is not a file" in err and not (out / "dt=1e-5").exists(), err


def test_a_run_manifest_naming_a_folder_of_a_run_files_name_is_refused_before_anything_is_removed(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(argv(out)) == 0
    (out / "series.csv").unlink()
    (out / "series.csv").mkdir()
    before = sorted(p.name for p in out.iterdir())
    capsys.readouterr()
    assert main(argv(out)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "series.csv is a folder" in err, err
    assert sorted(p.name for p in out.iterdir()) == before


def _cut(path: Path, n: int) -> None:
    path.write_bytes(path.read_bytes()[:-n])


@pytest.mark.parametrize("damage, words", [
    (lambda out: _cut(out / "series.csv", 3), None),  # a row being written: read up to the last whole one
    (lambda out: (out / "summary.json").write_text('{"status": "running", "pid": 1}'), None),  # a run going on
    (lambda out: (out / "summary.json").write_text('{"status": "ok", "ca'), "summary.json cannot be read"),
    (lambda out: (out / "summary.json").write_text("[" * 100_000 + "]" * 100_000), "nested deeper"),
    (lambda out: (out / "summary.json").write_text('{"case": 3}'), "case is a JSON int"),
    (lambda out: (out / "summary.json").write_text("[1, 2]"), "not a summary of a run"),
    (lambda out: (out / "series.csv").write_bytes(b"t,a\n1,2\n3,x\n4,5\n"), "line 3, column 'a': 'x' is not a number"),
    (lambda out: (out / "series.csv").write_bytes(b"\xff\xfe\x00t\n"), "not text"),
    (lambda out: (out / "eta_lumen.csv").write_bytes(b"t,z=x\n1,2\n"), "'z=x', not z=<position>"),
    (lambda out: open(out / "series.csv", "r+b").truncate(2**30 + 1), "more than a table of a run ever is"),
    (lambda out: ((out / "eta_lumen.csv").unlink(), _cut(out / "wall.pvd", 40)), "wall.pvd cannot be read"),
    (lambda out: ((out / "eta_lumen.csv").unlink(), _cut(out / "wall_000005.vtu", 400)),
     "wall_000005.vtu cannot be read as a snapshot"),
], ids=["row-being-written", "running", "summary-cut", "summary-deep", "summary-kinds", "summary-list",
        "not-a-number", "not-text", "eta-header", "table-huge", "pvd-cut", "snapshot-cut"])
def test_read_results_on_a_half_written_or_damaged_folder_reads_what_is_whole_or_says_which_file(
        tmp_path, damage, words):
    """Issue 36: a folder a run is writing (or was killed writing) reads as far as it is whole; a damaged or
    crafted one ends in one ResultsError naming the file, never a traceback from inside a parser."""
    import multilayer as ml

    out = tmp_path / "run"
    assert main(argv(out, plots=True)) == 0
    whole = ml.read_results(out)
    damage(out)
    if words is None:
        res = ml.read_results(out)
        assert 0 < len(res.t) <= len(whole.t) and np.array_equal(res.t, whole.t[:len(res.t)])
        return
    with pytest.raises(ml.ResultsError, match=re.escape(words)):
        ml.read_results(out)
