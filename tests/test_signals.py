"""SIGINT and SIGTERM end every command with one line, keeping what it wrote, at any moment.

Real signals sent to the console script (``multilayer`` next to this
Python) at chosen moments: while Python starts and imports, while a run
steps (``run``, ``resume``), while a sweep runs here, on a local Dask
cluster (its start included) or in a pool of processes.  A command that
SIGTERM stopped exits with 143; one that SIGINT stopped ends its process
by SIGINT, as Python does (``returncode == -2``), which a shell reports as
130 and which stops a shell loop.  In-process: a signal whose exception is
swallowed, a signal held back, a run in a thread stopped by another.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from runs import CASES

import multilayer.commands
import multilayer.commands.run as run_command
from multilayer.campaign import executor
from multilayer.case.casefile import load_case
from multilayer.commands.common import TERMINATED
from multilayer.commands.main import main
from multilayer.plugin import interrupts
from multilayer.runner import loop

SCRIPT = Path(sys.executable).with_name("multilayer")
PULSE = CASES / "pulse-koiter-thick.toml"
MEMBRANE = CASES / "membrane-mode.toml"  # the wall alone: a run of 0.02 s (1000 steps) takes about half a second
SMALL = ("mesh.nz=12", "mesh.nr=3", "output.every=5")
#: how the console script ends when a signal stopped its command
ENDED = {signal.SIGINT: -signal.SIGINT, signal.SIGTERM: TERMINATED}

console_script = pytest.mark.skipif(not SCRIPT.exists(), reason="the console script is not installed next to Python")
dask = pytest.mark.skipif(not executor.dask_installed(), reason="dask.distributed not installed (extra 'dask')")


def sets(*overrides: str) -> list[str]:
    return [a for o in overrides for a in ("--set", o)]


@contextmanager
def started(args, command=(str(SCRIPT),), **kwargs) -> Iterator[subprocess.Popen]:
    """The command ``args`` started (in a session of its own: it and its workers are one process group); killed
    with its group if it still runs when the block ends (a failed test)."""
    p = subprocess.Popen([*command, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, **kwargs)
    try:
        yield p
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.communicate()


def wait_for(condition, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def rows(path: Path) -> int:
    try:
        return max(0, len(path.read_text().splitlines()) - 1)
    except OSError:
        return 0


def status(folder: Path) -> str | None:
    try:
        return json.loads((folder / "summary.json").read_text())["status"]
    except (OSError, ValueError):
        return None


def one_line(err: str, name: str) -> str:
    """The one line a stopped command printed on stderr (after the lines it prints anyway: a sweep's progress)."""
    assert "Traceback" not in err and "ERROR" not in err, err
    lines = [line for line in err.splitlines() if not line.startswith(("sweep:", "[")) and line.strip()]
    assert len(lines) == 1 and name in lines[0], err
    return lines[0]


def sigterm_caught(pid: int) -> bool:
    """Whether process ``pid`` has a handler for SIGTERM (``SigCgt`` of /proc/PID/status): the command line's
    handlers are in (SIGINT's is installed first, so both are)."""
    text = Path(f"/proc/{pid}/status").read_text()
    mask = int(next(line for line in text.splitlines() if line.startswith("SigCgt")).split()[1], 16)
    return bool(mask >> (signal.SIGTERM - 1) & 1)


# -- the console script's start -----------------------------------------------------------------------------
@console_script
@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="reads /proc/PID/status")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_while_the_command_starts_and_imports_ends_it_with_one_line(tmp_path, sig):
    """From 0 to 0.8 s after the process starts: once the command line's handlers are in (read from /proc just
    before the signal), the command ends as the signal says with one line; before, only Python itself has
    started (its own start and ``site``: SIGTERM's default action, Python's KeyboardInterrupt).  Never exit 0."""
    handled = 0
    for k, delay in enumerate((0.0, 0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.4, 0.8)):
        with started(["run", PULSE, "--out", tmp_path / f"o{k}", "--quiet", "--no-plots",
                      *sets(*SMALL, "time.end=0.05")]) as p:
            time.sleep(delay)
            try:
                ours = sigterm_caught(p.pid)
            except (OSError, StopIteration):  # not yet a Python process
                ours = False
            p.send_signal(sig)
            _, err = p.communicate(timeout=60)
        if ours:
            handled += 1
            assert p.returncode == ENDED[sig], (delay, p.returncode, err)
            one_line(err, sig.name)
        elif sig == signal.SIGTERM:
            assert (p.returncode, err) == (-signal.SIGTERM, ""), (delay, p.returncode, err)
        else:
            assert p.returncode in (-signal.SIGINT, 1), (delay, p.returncode, err)
    assert handled >= 3  # the handlers are in after some 20-50 ms (Python's own start), up to 0.25 s under load


# -- runs ---------------------------------------------------------------------------------------------------
@console_script
def test_run_stopped_by_sigterm_exits_143_and_resume_stopped_by_sigint_ends_by_sigint(tmp_path):
    out = tmp_path / "out"
    with started(["run", PULSE, "--out", out, "--quiet", "--no-plots", "--checkpoint-every", "5",
                  *sets(*SMALL, "time.end=0.05")]) as p:
        wait_for(lambda: rows(out / "series.csv") >= 3)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    summary = json.loads((out / "summary.json").read_text())
    assert p.returncode == 143 and summary["status"] == "interrupted"
    assert one_line(err, "SIGTERM") == (f"run: {summary['reason']}; the results so far are in {out}, "
                                        f"continue with: multilayer resume {out}")
    assert summary["reason"].startswith("interrupted by SIGTERM after step")
    assert rows(out / "series.csv") == rows(out / "eta_lumen.csv") == summary["steps"] >= 3

    with started(["resume", out, "--quiet", "--no-plots"]) as p:
        wait_for(lambda: rows(out / "series.csv") >= summary["steps"] + 3)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    resumed = json.loads((out / "summary.json").read_text())
    assert p.returncode == -signal.SIGINT and resumed["reason"].startswith("interrupted by SIGINT after step")
    assert one_line(err, "SIGINT").startswith(f"resume: {resumed['reason']}; the results so far are in {out}")
    assert rows(out / "series.csv") == resumed["steps"] > summary["steps"]


@console_script
@pytest.mark.skipif(shutil.which("bash") is None or not Path("/proc/self/task").is_dir(), reason="bash and /proc")
def test_a_shell_reports_143_and_a_shell_loop_stops_on_ctrl_c(tmp_path):
    """``$?`` is 143 after SIGTERM; Ctrl-C (SIGINT to the terminal's process group) stops the loop itself, which
    bash does only when the command ended by SIGINT, not when it exited with 130."""
    command = f'"$0" run {PULSE} --out "{tmp_path}/o$i" --quiet --no-plots ' + " ".join(
        f"--set {s}" for s in (*SMALL, "time.end=0.05"))
    loop_script = f'for i in 1 2 3; do {command}; echo "exit $?"; done'
    with started([loop_script, SCRIPT], command=("bash", "-c")) as shell:
        wait_for(lambda: rows(tmp_path / "o1" / "series.csv") >= 2)
        child = Path(f"/proc/{shell.pid}/task/{shell.pid}/children").read_text().split()[0]
        os.kill(int(child), signal.SIGTERM)  # the command only, as `kill PID` would
        wait_for(lambda: rows(tmp_path / "o2" / "series.csv") >= 2)
        os.killpg(shell.pid, signal.SIGINT)  # Ctrl-C: bash and the command alike
        out, err = shell.communicate(timeout=60)
    assert out == "exit 143\n" and shell.returncode == -signal.SIGINT, (out, err)
    assert status(tmp_path / "o1") == status(tmp_path / "o2") == "interrupted" and status(tmp_path / "o3") is None


# -- sweeps -------------------------------------------------------------------------------------------------
def sweep_argv(out: Path, jobs: int) -> list[str]:
    return ["sweep", str(MEMBRANE), "--out", str(out), "--jobs", str(jobs), "--vary",
            "layers[0].tension=2e4,4e4,8e4,16e4", *sets("time.end=0.02")]


def runs(out: Path) -> dict[str, str | None]:
    return {f.name: status(f) for f in sorted((out / "runs").glob("*"))}


def in_flight(out: Path) -> bool:
    return any(s == "running" and (out / "runs" / name / "series.csv").is_file() for name, s in runs(out).items())


def resubmit(out: Path, capsys, before: dict[str, str | None]) -> None:
    """The same sweep again (here, one run after the other): the ok runs are kept, the others run."""
    stamps = {name: (out / "runs" / name / "summary.json").stat().st_mtime_ns for name, s in before.items()
              if s == "ok"}
    capsys.readouterr()
    assert main(sweep_argv(out, 1)) == 0
    assert f"4 runs, {len(stamps)} already done, {4 - len(stamps)} to run" in capsys.readouterr().err
    assert set(runs(out).values()) == {"ok"} and len(runs(out)) == 4
    assert stamps == {n: (out / "runs" / n / "summary.json").stat().st_mtime_ns for n in stamps}


@console_script
def test_a_sweep_here_stopped_by_sigterm_keeps_its_runs_and_a_resubmission_continues(tmp_path, capsys):
    out = tmp_path / "s"
    with started(sweep_argv(out, 1)) as p:
        wait_for(lambda: "ok" in runs(out).values() and in_flight(out))
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and one_line(err, "SIGTERM") == "multilayer: terminated (SIGTERM)"
    before = runs(out)  # the run in flight finished its step (none is left 'running'); no other began
    assert "ok" in before.values() and set(before.values()) <= {"ok", "interrupted"} and len(before) < 4, before
    resubmit(out, capsys, before)


@console_script
@dask
def test_ctrl_c_stops_a_dask_sweep_with_one_line_its_runs_in_flight_after_their_step(tmp_path, capsys):
    """SIGINT to the whole process group, the local cluster's workers included (as a terminal's Ctrl-C): no
    worker's traceback, the runs in flight stop after their step (none is left 'running'), no queued one begins."""
    out = tmp_path / "s"
    with started(sweep_argv(out, 2)) as p:
        wait_for(lambda: in_flight(out))
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=90)
    assert p.returncode == -signal.SIGINT and one_line(err, "SIGINT") == "multilayer: interrupted (SIGINT)"
    before = runs(out)
    assert "interrupted" in before.values() and set(before.values()) <= {"ok", "interrupted"}, before
    resubmit(out, capsys, before)


def spawned(pid: int) -> bool:
    """Whether process ``pid`` has started a process by ``multiprocessing`` (a Dask worker)."""
    for child in " ".join(p.read_text() for p in Path(f"/proc/{pid}/task").glob("*/children")).split():
        try:
            if b"spawn_main" in Path(f"/proc/{child}/cmdline").read_bytes():
                return True
        except OSError:
            pass
    return False


@console_script
@dask
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads /proc/PID/task")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_local_dask_cluster_starts_ends_the_sweep_with_one_line(tmp_path, sig):
    """Ctrl-C, or SIGTERM to the process group (a batch system's at the end of a job), once the first worker
    process is spawned, while it imports: no worker dies with a traceback, no cluster is left half started."""
    out = tmp_path / "s"
    with started(sweep_argv(out, 2)) as p:
        wait_for(lambda: spawned(p.pid))
        os.killpg(p.pid, sig)
        _, err = p.communicate(timeout=90)
    assert p.returncode == ENDED[sig] and one_line(err, sig.name).startswith("multilayer: ")
    assert "running" not in runs(out).values()


@console_script
def test_a_sweep_on_a_process_pool_stopped_by_sigterm_ends_with_one_line(tmp_path):
    """Without Dask, several jobs run in a pool of spawned processes: the signal is passed on to them."""
    out = tmp_path / "s"
    code = ("import sys\nfrom multilayer.campaign import executor\nexecutor.dask_installed = lambda: False\n"
            "from multilayer.commands import console\nsys.exit(console())")
    with started([code, *sweep_argv(out, 2)], command=(sys.executable, "-c")) as p:
        wait_for(lambda: in_flight(out))
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=90)
    assert p.returncode == 143 and one_line(err, "SIGTERM") == "multilayer: terminated (SIGTERM)"
    assert "2 local processes (Dask is not installed)" in err
    assert set(runs(out).values()) <= {"ok", "interrupted"} and len(runs(out)) < 4, runs(out)


# -- in-process ---------------------------------------------------------------------------------------------
def test_a_signal_whose_exception_is_swallowed_still_ends_the_command_with_its_code(tmp_path, monkeypatch, capsys):
    real = run_command.load_case

    def swallowing(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
        except BaseException:  # a library that catches everything and goes on
            pass
        return real(*args, **kwargs)

    monkeypatch.setattr(run_command, "load_case", swallowing)
    a = ["run", str(PULSE), "--out", str(tmp_path / "out"), "--quiet", "--no-plots", *sets(*SMALL, "time.end=0.001")]
    assert multilayer.commands.cli(a) == TERMINATED
    assert capsys.readouterr().err == "multilayer: terminated (SIGTERM)\n"
    assert status(tmp_path / "out") == "ok"  # the command went on to its end, and still says it was terminated


def test_a_signal_whose_exception_an_import_turns_into_another_ends_the_command_with_its_code(monkeypatch, capsys):
    """A Cython or Pythran module whose initialization the signal's exception stops raises
    ``ImportError: initialization failed`` instead (seen with SciPy's ``_ckdtree``): the signal still ends it."""
    import multilayer.commands.main as main_module

    def importing(argv):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
        except BaseException:  # what an extension module's init does with an exception raised in it
            raise ImportError("initialization failed") from None
        return 0

    monkeypatch.setattr(main_module, "main", importing)
    assert multilayer.commands.cli(["run", "x.toml"]) == TERMINATED
    assert capsys.readouterr().err == "multilayer: terminated (SIGTERM)\n"

    def failing(argv):
        raise ImportError("a plain failure, no signal")

    monkeypatch.setattr(main_module, "main", failing)
    with pytest.raises(ImportError, match="no signal"):  # without a signal, an exception is what it is
        multilayer.commands.cli(["run", "x.toml"])


def test_a_signal_held_back_is_raised_at_the_end_of_the_block_even_when_the_block_fails():
    handler = interrupts.CommandSignals()
    previous = handler.install()
    try:
        with pytest.raises(interrupts.Terminated):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.1)  # not raised here
                done = True
        assert done
        with pytest.raises(interrupts.UserInterrupt):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.1)
                raise RuntimeError("a worker the signal ended")
        with interrupts.deferred():  # no signal: nothing raised
            pass
        assert handler.received == ["SIGTERM", "SIGINT"] and handler.raising
    finally:
        for sig, h in previous.items():
            signal.signal(sig, h)
    with interrupts.deferred():  # outside the command line: nothing changes
        pass


def test_a_run_in_another_thread_is_stopped_after_its_step_as_a_signal_would():
    case = load_case(PULSE, [*SMALL, "time.end=0.05", "output.every=0"])
    results = {}

    def progress(tally, row):
        if tally.steps == 3:
            assert loop.runs() == [worker.ident]
            assert loop.stop("SIGTERM", threading.main_thread().ident) == []  # no run there
            assert loop.stop("SIGTERM", worker.ident) == [worker.ident]

    worker = threading.Thread(target=lambda: results.update(r=loop.run_held(case, progress=progress)[0]))
    worker.start()
    worker.join(60)
    result = results["r"]
    assert (result.status, result.steps, result.signal) == ("interrupted", 3, "SIGTERM")
    assert result.reason == "interrupted by SIGTERM after step 3 (t = 0.0003 s)" and loop.runs() == []


def test_a_run_whose_step_a_signal_cuts_short_with_another_exception_is_interrupted_not_failed():
    """A signal that lands inside an extension's call can surface as another exception there (pybind11's
    RuntimeError "Caught an unknown exception!", seen in a pool worker's setup under SIGTERM): the run was
    stopped by the signal, so it is "interrupted" by it, the surfaced exception named in the reason."""
    case = load_case(PULSE, [*SMALL, "time.end=0.05", "output.every=0"])
    results = {}

    def progress(tally, row):
        if tally.steps == 3:
            loop.stop("SIGTERM", worker.ident)
            raise RuntimeError("Caught an unknown exception!")

    worker = threading.Thread(target=lambda: results.update(r=loop.run_held(case, progress=progress)[0]))
    worker.start()
    worker.join(60)
    result = results["r"]
    assert (result.status, result.steps, result.signal) == ("interrupted", 3, "SIGTERM")
    assert result.reason == ("interrupted by SIGTERM after step 3 (t = 0.0003 s; on the way: RuntimeError after "
                             "step 3: Caught an unknown exception!)")


def test_check_plugin_stopped_by_a_signal_during_its_coupled_run_is_no_failed_check(monkeypatch, capsys):
    import multilayer.testing

    real = multilayer.testing.run_case

    def run_case(*args, **kwargs):
        def progress(tally, row):
            if tally.steps == 2:
                os.kill(os.getpid(), signal.SIGTERM)

        return real(*args, **kwargs, progress=progress)

    monkeypatch.setattr(multilayer.testing, "run_case", run_case)
    assert multilayer.commands.cli(["check-plugin", "wave-membrane"]) == TERMINATED
    captured = capsys.readouterr()
    assert "FAIL" not in captured.out and captured.err == "multilayer: terminated (SIGTERM)\n"
