"""The edges of a run: a signal or a full disk at any moment ends it with one line and a consistent folder.

Consistent: ``series.csv`` and ``eta_lumen.csv`` end on the same step, the
summary says how many steps and why the run stopped, no ``.lock`` and no
``.*.tmp`` are left, every snapshot listed in a ``.pvd`` is on disk whole.
"""

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from runs import CASES

import multilayer.commands
import multilayer.results.files
from multilayer.case.casefile import load_case
from multilayer.commands.common import INTERRUPTED
from multilayer.plugin.interrupts import UserInterrupt
from multilayer.results.files import SeriesWriter
from multilayer.results.folder import ResultsFolder
from multilayer.runner.loop import run_case

SMALL = ["mesh.nz=12", "mesh.nr=3", "output.every=5"]


def case(end=0.002):
    return load_case(CASES / "pulse-koiter-thick.toml", [*SMALL, f"time.end={end}"])


def rows(path: Path) -> int:
    return len(path.read_text().splitlines()) - 1 if path.exists() else 0


def assert_consistent(out: Path) -> dict:
    """The folder's invariants; its summary."""
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] in ("ok", "failed", "interrupted"), summary["status"]
    assert rows(out / "series.csv") == rows(out / "eta_lumen.csv") == summary["steps"]
    names = [p.name for p in out.iterdir()]
    assert ".lock" not in names and not [n for n in names if n.endswith(".tmp")], names
    for pvd in out.glob("*.pvd"):
        for entry in ET.parse(pvd).getroot().iter("DataSet"):
            ET.parse(out / entry.get("file"))  # whole XML
    return summary


# -- signals ------------------------------------------------------------------------------------------------
def test_a_signal_while_the_folder_is_made_stops_the_run_before_its_first_step(tmp_path, monkeypatch):
    real = ResultsFolder._reserve_summary

    def reserve(self):
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)  # a second one too: the folder is made whole all the same
        real(self)

    monkeypatch.setattr(ResultsFolder, "_reserve_summary", reserve)
    result = run_case(case(), tmp_path / "out")
    assert result.status == "interrupted" and result.steps == 0
    summary = assert_consistent(tmp_path / "out")
    assert summary["reason"].startswith("interrupted by SIGINT after step 0")


def test_a_second_sigint_while_a_step_is_written_keeps_the_folder_consistent(tmp_path, monkeypatch):
    real = SeriesWriter.append

    def append(self, row):
        if row.get("step") == 5 and self.path.name == "series.csv":
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)
        real(self, row)

    monkeypatch.setattr(SeriesWriter, "append", append)
    result = run_case(case(), tmp_path / "out")
    assert result.status == "interrupted" and result.steps == 5
    assert assert_consistent(tmp_path / "out")["steps"] == 5


def test_a_second_sigint_during_a_step_abandons_it(tmp_path):
    def progress(tally, row):
        if tally.steps == 3:
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)  # between two writes: the step in the making is dropped

    result = run_case(case(), tmp_path / "out", progress=progress)
    assert result.status == "interrupted" and result.steps == 3
    assert_consistent(tmp_path / "out")


def test_signals_while_the_summary_is_written_do_not_cut_it(tmp_path, monkeypatch):
    real = ResultsFolder.write_summary

    def write_summary(self, summary):
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)
        return real(self, summary)

    monkeypatch.setattr(ResultsFolder, "write_summary", write_summary)
    handlers = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    result = run_case(case(), tmp_path / "out")
    assert result.status == "ok" and result.steps == 20  # the run was over: the signals change nothing
    assert assert_consistent(tmp_path / "out")["status"] == "ok"
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers


@pytest.mark.parametrize("where", ["multilayer.case.casefile.load_case", "multilayer.commands.plot.plot_folder"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_outside_a_run_ends_the_command_with_one_line(tmp_path, monkeypatch, capsys, where, sig):
    """Before the run (reading the case) and after it (drawing the figures): exit 128 + the signal."""
    import multilayer.commands.run as run_command

    name = where.rsplit(".", 1)[1]
    real = getattr(run_command, name)

    def signalled(*args, **kwargs):
        os.kill(os.getpid(), sig)
        time.sleep(1)  # the handler raises before this ends
        return real(*args, **kwargs)

    monkeypatch.setattr(run_command, name, signalled)
    a = ["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(tmp_path / "out"), "--quiet",
         *(x for s in (*SMALL, "time.end=0.001") for x in ("--set", s))]
    assert multilayer.commands.cli(a) == 128 + sig
    err = capsys.readouterr().err
    assert err.strip() in ("multilayer: interrupted (SIGINT)", "multilayer: terminated (SIGTERM)") and "Traceback" not in err
    if (tmp_path / "out").exists():  # the run had ended: its folder is whole
        assert assert_consistent(tmp_path / "out")["status"] == "ok"


def test_a_sigint_while_plugins_load_is_not_a_broken_plugin(monkeypatch, capsys):
    from multilayer.plugin import registry

    real = registry.Registry.load

    def load(*args, **kwargs):
        raise UserInterrupt

    monkeypatch.setattr(registry.Registry, "load", load)
    assert multilayer.commands.cli(["plugins"]) == INTERRUPTED
    assert "interrupted (SIGINT)" in capsys.readouterr().err
    monkeypatch.setattr(registry.Registry, "load", real)


def _importing_numpy(pid: int, timeout: float = 60.0) -> None:
    """Wait until process ``pid`` has numpy's extension mapped: the command's own imports have begun, so
    :func:`multilayer.commands.cli` has taken SIGINT over (before that, Python's start-up is Python's own)."""
    maps, end = Path(f"/proc/{pid}/maps"), time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            if "numpy" in maps.read_text():
                return
        except OSError:
            return
        time.sleep(0.005)


def test_ctrl_c_on_the_command_line_at_any_moment(tmp_path):
    """The console script, a real SIGINT at several moments from its imports on (imports, setup, steps): the
    process ends by SIGINT (a shell reports 130; see tests/test_signals.py), with no traceback, and the folder,
    when there is one, consistent.  The moments count from the command's first import of numpy, not from the
    process's start: on a loaded machine Python's own start-up can outlast a fixed delay, and a SIGINT there is
    Python's, not the command's."""
    script = Path(sys.executable).with_name("multilayer")
    if not script.exists():
        pytest.skip("the console script is not installed next to this Python")
    for k, delay in enumerate((0.0, 0.6, 1.4, 2.4)):
        out = tmp_path / f"out{k}"
        args = [str(script), "run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out), "--quiet",
                "--no-plots", *(x for s in (*SMALL, "time.end=0.2") for x in ("--set", s))]
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if Path("/proc").is_dir():
            _importing_numpy(p.pid)
        else:
            delay += 0.6
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
        assert p.returncode == -signal.SIGINT and "Traceback" not in err, (delay, p.returncode, err)
        if (out / "summary.json").exists():
            assert assert_consistent(out)["status"] == "interrupted"


# -- a full disk ----------------------------------------------------------------------------------------------
def test_a_row_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    writer = SeriesWriter(tmp_path / "s.csv", ["step", "t"])
    writer.append({"step": 1, "t": 0.5})
    before = (tmp_path / "s.csv").read_bytes()
    real = os.write
    calls = []

    def short_then_full(fd, data):
        calls.append(len(data))
        if len(calls) == 1:
            return real(fd, data[:3])  # part of the row reaches the disk
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(multilayer.results.files.os, "write", short_then_full)
    with pytest.raises(OSError) as info:
        writer.append({"step": 2, "t": 1.0})
    monkeypatch.setattr(multilayer.results.files.os, "write", real)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(tmp_path / "s.csv")
    assert (tmp_path / "s.csv").read_bytes() == before
    writer.append({"step": 2, "t": 1.0})
    writer.undo()  # the partner file could not take its row
    assert (tmp_path / "s.csv").read_bytes() == before


def _tmpfs_available() -> bool:
    if shutil.which("unshare") is None or shutil.which("mount") is None:
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt 2>/dev/null || "
                            "mount -t tmpfs -o size=64k tmpfs /tmp"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _tmpfs_available(), reason="needs a private tmpfs (unshare -rm, mount)")
def test_a_full_disk_at_every_moment_leaves_a_consistent_folder(tmp_path):
    """Real full disks (a small tmpfs in a private mount namespace): at the start, in mid-run, at the end.

    The sizes come from the complete folder of the same run: less than the summary's reserved room (the
    start), half the folder without figures (mid-run), the folder without figures plus a little (the
    figures at the end).  Each ends with one line on stderr, no traceback, and a consistent folder.
    """
    script = Path(sys.executable).with_name("multilayer")
    if not script.exists():
        pytest.skip("the console script is not installed next to this Python")
    sets = [x for s in (*SMALL, "time.end=0.005") for x in ("--set", s)]
    full = tmp_path / "complete"
    assert subprocess.run([str(script), "run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(full),
                           "--quiet", *sets], capture_output=True).returncode == 0
    pages = lambda p: -(-p.stat().st_size // 4096) * 4096  # noqa: E731  tmpfs counts whole pages
    figures = sum(pages(p) for p in full.glob("*.png"))
    data = sum(pages(p) for p in full.iterdir()) - figures + ResultsFolder.RESERVE
    moments = {"start": 16 << 10, "mid-run": data // 2, "end": data + (16 << 10)}
    for moment, size in moments.items():
        mnt, keep = tmp_path / f"mnt-{moment}", tmp_path / f"kept-{moment}"
        mnt.mkdir()
        shell = (f"mount -t tmpfs -o size={size} tmpfs {mnt} || exit 99; "
                 f"{script} run {CASES / 'pulse-koiter-thick.toml'} --out {mnt}/out --quiet {' '.join(sets)} "
                 f"2> {tmp_path}/err-{moment}; echo $? > {tmp_path}/rc-{moment}; "
                 f"if [ -d {mnt}/out ]; then cp -a {mnt}/out {keep}; fi")
        assert subprocess.run(["unshare", "-rm", "sh", "-c", shell]).returncode == 0, moment
        rc = int((tmp_path / f"rc-{moment}").read_text())
        err = (tmp_path / f"err-{moment}").read_text()
        assert "Traceback" not in err and "No space left on device" in err, (moment, err)
        assert len(err.strip().splitlines()) <= 2, (moment, err)  # the run's line; at the end also the figures'
        if moment == "start":
            assert rc == 2 and not keep.exists()  # nothing was made
            continue
        summary = assert_consistent(keep)
        if moment == "mid-run":
            assert rc == 1 and summary["status"] == "failed" and "No space left on device" in summary["reason"]
            assert 0 < summary["steps"] < 50
        else:
            assert rc == 0 and summary["status"] == "ok" and summary["steps"] == 50
            assert "figures" in err and not all((keep / p.name).exists() for p in full.glob("*.png"))
