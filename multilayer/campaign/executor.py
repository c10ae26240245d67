"""Running many runs: here one after the other, or on Dask (an embedded local cluster or an existing one).

Every command that runs more than one case — ``compare``, ``study``,
``stability`` and ``sweep`` — hands its runs to :func:`execute` as
:class:`Job` s (a case file, its overrides, a results folder: everything
picklable).  How they run:

* ``serial``: in this process, one after the other (one worker and no
  scheduler).  Needs nothing beyond the default install.
* ``dask``: on a Dask cluster: ``--scheduler tcp://host:8786`` submits to an
  existing one, otherwise an embedded :class:`distributed.LocalCluster` of
  N worker processes (one thread each) is started and stopped here.  A worker
  that dies loses only the run it held, which the scheduler runs again.
* ``processes``: a pool of N spawned processes, when Dask is not installed
  (``pip install 'multilayer[dask]'``).

A SIGINT or SIGTERM that stops the command (:mod:`multilayer.plugin.interrupts`)
stops its runs too: queued ones never start, those in flight finish their
step and stop, ``interrupted`` (a run here catches the signal itself;
:func:`execute` tells Dask workers and pool processes), and the command's
exception is raised again once they have (or after :data:`STOP_WAIT`
seconds).  The runs that ended are kept in their folders.

A worker builds its plugin registry from the installed plugins plus the
``--plugin`` modules: a ``.py`` file is shipped as its source text
(:class:`Plugin`), a dotted module name must be importable on the worker.
Case files, the tables they name and the results folders are read and
written at the same paths by every worker: on a cluster of several machines
they must be on a shared file system.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import logging
import multiprocessing
import os
import signal
import sys
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed, wait
from contextlib import contextmanager
from multiprocessing import resource_tracker
from pathlib import Path
from types import ModuleType

import attrs

from multilayer.campaign import dask_worker
from multilayer.campaign.variants import run_variant
from multilayer.case.casefile import load_case
from multilayer.plugin.interrupts import deferred, signal_name, stopped
from multilayer.plugin.loading import import_plugin
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry, RegistryError
from multilayer.runner.loop import RunResult, runs

#: times Dask runs a job again after it raised (a dead worker is rescheduled by the scheduler itself,
#: up to its ``distributed.scheduler.allowed-failures``)
RETRIES = 2


#: Dask configuration of the embedded cluster's workers.  Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in a
#: worker's environment; glibc then gives up its dynamic mmap threshold and every large temporary array is a
#: fresh mmap: a run took 1.8x as long (measured, docs/sweeps.md).  None unsets it (the worker threads stay 1
#: BLAS thread each, Dask's default).
WORKER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}

#: seconds the command, stopped by a signal, waits for its runs in flight to finish their step and stop
STOP_WAIT = 60.0


class ExecutorError(Exception):
    """The runs cannot be started as asked (Dask missing, scheduler unreachable); the message says why."""


@attrs.frozen
class Job:
    """What a worker needs to run one case: everything picklable."""

    label: str
    case_file: Path
    overrides: tuple[str, ...]
    folder: Path


@attrs.frozen
class Plugin:
    """One ``--plugin``, as a worker loads it: a ``.py`` file travels as its source, a module by name."""

    spec: str  #: as given on the command line
    name: str  #: the module's name
    source: str | None = None  #: the file's text; None for a module that must be importable where the run is

    @classmethod
    def ship(cls, spec: str) -> Plugin:
        """The ``--plugin`` ``spec`` ready to travel; RegistryError when its file cannot be read."""
        if not spec.endswith(".py"):
            return cls(spec, spec)
        path = Path(spec)
        try:
            return cls(spec, path.stem, path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise RegistryError(f"--plugin {spec}: cannot read it ({exc})") from None

    def load(self) -> ModuleType:
        """Import the module here (a shipped file from its source)."""
        if self.source is None:
            return import_plugin(self.spec)
        spec = importlib.util.spec_from_loader(self.name, loader=None, origin=self.spec)
        module = importlib.util.module_from_spec(spec)
        module.__file__ = self.spec
        try:
            exec(compile(self.source, self.spec, "exec"), module.__dict__)
        except Exception as exc:  # a user's module: any error means "cannot load it"
            raise RegistryError(f"--plugin {self.spec}: cannot import it ({type(exc).__name__}: {exc})") from None
        return module


def ship_plugins(specs: Sequence[str]) -> tuple[Plugin, ...]:
    """Every ``--plugin`` ready to travel to a worker (see :class:`Plugin`)."""
    return tuple(Plugin.ship(spec) for spec in specs)


_REGISTRIES: dict[str, Registry] = {}


def worker_registry(plugins: tuple[Plugin, ...]) -> Registry:
    """The registry of a worker process for these plugins, built once per process and plugin set.

    A registry holds plugin records only (factories, parameter schemas),
    never the state of a run, so runs on one worker may share it.
    """
    key = hashlib.sha256(repr(plugins).encode()).hexdigest()
    if key not in _REGISTRIES:
        _REGISTRIES[key] = Registry.load(extra=[p.load() for p in plugins])
    return _REGISTRIES[key]


def run_job(job: Job, registry: Registry) -> RunResult:
    """Run one job into its folder with ``registry``: its result; never raises for a run's failure."""
    try:
        case = load_case(job.case_file, job.overrides, registry)
    except CaseError as exc:  # validated before; only a plugin or file that changed in between gets here
        return RunResult("failed", f"invalid case: {exc}", job.folder)
    name = _pool_signals[0] if _pool_signals else dask_worker.stopped_here()  # its command was stopped meanwhile
    if name is not None:
        return RunResult("interrupted", f"interrupted by {name} before its first step", job.folder, signal=name)
    return run_variant(case, job.folder, registry)


def run_shipped(job: Job, plugins: tuple[Plugin, ...]) -> tuple[str, str]:
    """A worker's entry point: the registry of ``plugins`` (:func:`worker_registry`), then :func:`run_job`:
    (status, reason)."""
    try:
        registry = worker_registry(plugins)
    except RegistryError as exc:
        return "failed", f"plugins on the worker: {exc}"
    result = run_job(job, registry)
    if result.signal and _pool_process:  # the run caught it: the command is being stopped
        _pool_signals.append(result.signal)
    return result.status, result.reason


def dask_installed() -> bool:
    """Whether ``dask.distributed`` can be imported (the optional extra ``dask``)."""
    return importlib.util.find_spec("distributed") is not None


def how(workers: int, scheduler: str | None = None) -> str:
    """The way :func:`execute` runs jobs: ``serial``, ``dask`` or ``processes``.

    >>> how(1)
    'serial'
    """
    if scheduler is not None:
        return "dask"
    if workers == 1:
        return "serial"
    return "dask" if dask_installed() else "processes"


def _wall_time(folder: Path) -> float | None:
    try:
        return json.loads((folder / "summary.json").read_text()).get("wall_time_s")
    except (OSError, ValueError):
        return None


class Progress:
    """One line per finished run: ``[done/total] label: status, wall time · running R, queued Q, failed F``.

    ``running`` is the runs the workers hold (at most one per worker
    thread), ``queued`` the rest of those not finished.
    """

    def __init__(self, total: int, log: Callable[[str], None]):
        self.total, self.log = total, log
        self.results: dict[str, tuple[str, str]] = {}
        self.failed = 0

    def finished(self, job: Job, status: str, reason: str, slots: int) -> None:
        """Log the run of ``job`` as finished; ``slots`` runs can go on at once."""
        self.results[job.label] = status, reason
        self.failed += status != "ok"
        wall = _wall_time(job.folder)
        left = self.total - len(self.results)
        self.log(f"[{len(self.results)}/{self.total}] {job.label}: {status}" + (f" ({reason})" if reason else "")
                 + (f", {wall:.3g} s" if wall is not None else ", no summary.json")
                 + f" · running {min(left, slots)}, queued {max(0, left - slots)}, failed {self.failed}")


def execute(jobs: Sequence[Job], workers: int, registry: Registry, plugins: Sequence[str] = (),
            log: Callable[[str], None] = print, scheduler: str | None = None) -> dict[str, tuple[str, str]]:
    """Run every job, ``workers`` at a time: (status, reason) by label.

    Parameters
    ----------
    jobs : sequence of Job
        Validated runs, submitted in this order.
    workers : int
        Runs at once: 1 runs them here one after the other; more start a
        local Dask cluster of that many worker processes (a process pool
        without Dask).  Ignored with ``scheduler``.
    registry : Registry
        The plugins of the runs made in this process.
    plugins : sequence of str
        The ``--plugin`` modules, loaded again by every worker.
    log : callable
        Gets one line per finished run (:class:`Progress`).
    scheduler : str, optional
        The address of an existing Dask scheduler (``tcp://host:8786``).

    Returns
    -------
    dict
        (status, reason) by label.  A run that fails, or whose worker died
        more often than the scheduler allows, is a failed run; the others
        go on.

    Raises
    ------
    ExecutorError
        Dask is needed and not installed, or the scheduler cannot be reached.
    """
    progress = Progress(len(jobs), log)
    if not jobs:
        return {}
    way = how(workers, scheduler)
    if way != "serial":  # another process, maybe on another machine, reads and writes them
        jobs = [attrs.evolve(j, case_file=Path(j.case_file).resolve(), folder=Path(j.folder).resolve()) for j in jobs]
    if way == "serial":
        for job in jobs:
            result = run_job(job, registry)
            progress.finished(job, result.status, result.reason, slots=1)
            if result.signal:  # the run caught the signal meant for the command, and stopped: so does the command
                raise stopped(result.signal)
    elif way == "dask":
        _on_dask(jobs, workers, ship_plugins(plugins), progress, scheduler)
    else:
        _on_processes(jobs, workers, ship_plugins(plugins), progress)
    return progress.results


#: the signals a pool process got (while it ran a run, or not): it starts no run after one
_pool_signals: list[str] = []
_pool_process = False  #: this process is a pool's (:func:`_pool_process_start`)


def _pool_process_start() -> None:
    """A pool process's SIGINT and SIGTERM outside a run (a run catches both itself): :func:`_pool_signal`."""
    global _pool_process
    _pool_process = True
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _pool_signal)


def _pool_signal(signum: int, frame: object) -> None:
    """A Ctrl-C reaches every process of the terminal's group, and the command stops the pool's runs and passes
    its signal on (:func:`_stop_processes`): a pool process records the signal and starts no run after it (the
    idle one would otherwise die of SIGINT with a traceback); SIGTERM ends an idle one, as by default."""
    _pool_signals.append(signal.Signals(signum).name)
    if signum == signal.SIGTERM and not runs():
        os._exit(128 + signum)


def _on_processes(jobs: Sequence[Job], workers: int, plugins: tuple[Plugin, ...], progress: Progress) -> None:
    context = multiprocessing.get_context("spawn")
    slots = min(workers, len(jobs))
    pool = ProcessPoolExecutor(max_workers=slots, mp_context=context, initializer=_pool_process_start)
    futures = {pool.submit(run_shipped, job, plugins): job for job in jobs}
    try:
        for future in as_completed(futures):
            _finished(future, futures[future], progress, slots)
    except BaseException as exc:
        for future in futures:  # here, not in the pool's thread as shutdown would: then waited for below
            future.cancel()
        pool.shutdown(wait=False, cancel_futures=True)
        name = signal_name(exc)
        if name is not None:
            _stop_processes(futures, name, progress, slots)
        raise
    pool.shutdown()


def _finished(future: Future, job: Job, progress: Progress, slots: int) -> None:
    try:
        status, reason = future.result()
    except Exception as exc:  # the worker died (out of memory, killed) or was lost: that run failed
        status, reason = "failed", f"{type(exc).__name__}: {exc}"
    progress.finished(job, status, reason, slots)


def _stop_processes(futures: dict[Future, Job], name: str, progress: Progress, slots: int) -> None:
    """The command was stopped by the signal ``name`` (its pool shut down, the queued runs cancelled): pass the
    signal on to the pool's processes (a run stops after its step, a process starts no run after it:
    :func:`_pool_signal`) and wait for the runs in flight, at most :data:`STOP_WAIT` seconds."""
    for child in multiprocessing.active_children():  # the pool's (this process starts no other on this path)
        try:
            os.kill(child.pid, signal.Signals[name])
        except OSError:  # it has just ended
            pass
    done, _ = wait([f for f in futures if not f.done()], timeout=STOP_WAIT)
    for future in done:  # an idle process that SIGTERM ended broke the pool: those runs' folders say how they ended
        if not future.cancelled() and future.exception() is None:
            _finished(future, futures[future], progress, slots)


def _on_dask(jobs: Sequence[Job], workers: int, plugins: tuple[Plugin, ...], progress: Progress,
             scheduler: str | None) -> None:
    if not dask_installed():
        raise ExecutorError("running on Dask needs dask.distributed: pip install 'multilayer[dask]'"
                            + ("" if scheduler else " (or use --jobs 1)"))
    # dask is an optional extra (and heavy): imported only to run on it
    import dask
    import distributed

    cluster = client = None
    environ = dict(os.environ)  # a local nanny writes its workers' variables into this process's environment
    quiet = logging.getLogger("distributed")  # the scheduler's and the nannies' of a local cluster, the client's
    level = quiet.level
    try:
        try:
            with deferred(), _signals_blocked():  # a signal meanwhile: once the cluster is up, to be closed whole
                if scheduler is None:
                    with dask.config.set(WORKER_CONFIG):
                        cluster = distributed.LocalCluster(n_workers=min(workers, len(jobs)), threads_per_worker=1,
                                                           processes=True, dashboard_address=":0",
                                                           scheduler_kwargs={"dashboard": False},
                                                           silence_logs=logging.ERROR,
                                                           preload=[dask_worker.__name__])
                client = distributed.Client(cluster if cluster is not None else scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            where = f"the Dask scheduler at {scheduler}" if scheduler else "a local Dask cluster"
            raise ExecutorError(f"cannot reach {where}: {exc}") from None
        futures = {client.submit(run_shipped, job, plugins, pure=False, retries=RETRIES,
                                 key=f"multilayer-{i}-{uuid.uuid4().hex[:12]}"): job for i, job in enumerate(jobs)}
        try:
            for future in distributed.as_completed(futures):
                slots = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
                _finished(future, futures[future], progress, max(1, slots))
        except BaseException as exc:
            name = signal_name(exc)
            if name is not None:
                quiet.setLevel(logging.CRITICAL)  # a worker ending meanwhile is expected now, not an error to log
                _stop_on_dask(client, futures, name, progress)
            raise
    finally:
        try:
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
        finally:
            quiet.setLevel(level)
            _restore_environment(environ)


@contextmanager
def _signals_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread for the block, and so in the threads it starts and the processes
    those start: the embedded cluster's nannies start its workers with both blocked, so a Ctrl-C or a SIGTERM to
    the whole process group cannot end a worker while it starts (with a traceback); its preload
    (:func:`multilayer.campaign.dask_worker.dask_setup`) installs its handlers, then unblocks them (as
    ``multiprocessing`` starts its resource tracker).  The tracker is started first: starting it unblocks both
    in the thread that does."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    resource_tracker.ensure_running()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _stop_on_dask(client, futures: dict, name: str, progress: Progress) -> None:
    """The command was stopped by the signal ``name``: stop the runs the workers hold
    (:func:`multilayer.campaign.dask_worker.stop_tasks`: each finishes its step), cancel the others and wait
    for the stopped ones, at most :data:`STOP_WAIT` seconds.  Best effort: a run that does not stop here is one
    the next submission runs again."""
    import distributed

    flight = [f for f in futures if not f.done()]
    try:
        held = client.run(dask_worker.stop_tasks, [f.key for f in flight], name, on_error="ignore")
        held = {key for keys in held.values() for key in keys}
        client.cancel([f for f in flight if f.key not in held])
        stopping = [f for f in flight if f.key in held]
        distributed.wait(stopping, timeout=STOP_WAIT)
    except Exception:  # a worker lost meanwhile, the wait timed out: the cluster is closed all the same
        return
    for future in stopping:
        _finished(future, futures[future], progress, len(stopping))


def _restore_environment(saved: dict[str, str]) -> None:
    """Put this process's environment back as it was (Dask's nanny sets OMP_NUM_THREADS=1 and more in it)."""
    for key in set(os.environ) - set(saved):
        del os.environ[key]
    os.environ.update(saved)


def print_err(line: str) -> None:
    """Log to stderr (the progress lines of the grid commands)."""
    print(line, file=sys.stderr, flush=True)
