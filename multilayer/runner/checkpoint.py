"""Checkpoints: the whole state of a run, written as data, and read back — checked — to resume it.

A checkpoint is two files in the results folder:

* ``checkpoint.npz`` — every array (``np.savez``; read with ``allow_pickle=False``, so an object
  array is refused, never unpickled);
* ``checkpoint.json`` — everything else: the format and its version, the resolved case (with the
  folder its table files are read from), its digest, the plugin versions, the coupler's
  :class:`~multilayer.scene.state.State` (every field and every older level a scheme needs), the
  run's tally (the ledger's running total, the energy bound, counts), the snapshot collections,
  the held state of every reusing solver (:mod:`multilayer.numerics.held`:
  the matrix its factors are of, their precision, the break-even counters, GMRES's guess span),
  each array as a reference ``{"array": name}`` into the npz, and ``sha256``, a SHA-256 digest
  over the content of both (the canonical JSON without the digest, then every array's name,
  dtype, shape and bytes).

Values are written by a small explicit encoder (:func:`encode`: None, booleans, whole numbers,
numbers, strings, arrays, lists, and tuples and mappings tagged as such) and read back into the
known types only: the State and WallState here, the fluid's state by the fluid
(:meth:`~multilayer.fluid.contract.Fluid.state_from_data`), the ends' states by their conditions.
Nothing in the files is evaluated or unpickled.

Resuming checks, and refuses with :class:`CheckpointError` (``multilayer resume`` exits 2 with
the message): a folder without a checkpoint, or with only a ``checkpoint.pkl`` of an older
version (never read: unpickling runs code); a file that is truncated, not JSON or not an npz,
another format, a newer format version, a digest that does not match (a flipped bit), an object
array, a missing key or a field of the wrong type or shape; other plugin versions, or a case that
resolves differently (only ``time.end`` may move, with ``--until``).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from multilayer.case.casefile import validate_data
from multilayer.case.model import Case
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry, plugin_versions
from multilayer.results.files import atomic_file
from multilayer.results.folder import ResultsFolder, run_identity, snapshot_of
from multilayer.runner.volume import VolumeLedger
from multilayer.scene.state import State, WallState
from multilayer.version import __version__

FILE = "checkpoint.json"  #: the checkpoint's entry point (the arrays are in :data:`ARRAYS`)
ARRAYS = "checkpoint.npz"
LEGACY = "checkpoint.pkl"  #: what versions before 2 wrote: a pickle, never read
MAGIC = "multilayer-checkpoint"
#: the largest ``checkpoint.json`` read (bytes): the case, the plugins and the structure, never an array
MAX_DOCUMENT = 64 * 2**20
#: the largest checkpoint.npz read (a run's fields and held factors: megabytes for the cases run here)
MAX_ARRAYS = 8 * 2**30
FORMAT = 3  #: the format version: a newer one is refused (3: the owning run's identity)
#: the dtypes an array of a checkpoint may have
DTYPES = ("b", "i", "u", "f", "c")


class CheckpointError(Exception):
    """No usable checkpoint, or one that does not belong to this case and these plugins."""


@attrs.frozen(eq=False)
class Checkpoint:
    """A checkpoint as read: the case, the tally and snapshots rebuilt; the state and solvers as data
    until :func:`restore` rebuilds them on the run's setup."""

    case: Case
    state: Any  #: the State's data (:func:`restore` makes the State)
    tally: Any
    snapshots: Mapping[str, list]
    checkpoint_every: int
    solvers: list = attrs.field(factory=list)  #: [(name, held state)] of the reusing solvers


# -- encoding values as JSON and arrays -------------------------------------------
def encode(value: Any, arrays: dict[str, np.ndarray]) -> Any:
    """``value`` as JSON, its arrays added to ``arrays`` (as ``a0``, ``a1``, ...) and referenced by name.

    None, booleans, strings and finite numbers are themselves; a non-finite number is
    ``{"float": "inf"}`` (or ``-inf``, ``nan``); an array ``{"array": name}``; a list a list; a tuple
    ``{"tuple": [...]}``; a mapping with string keys ``{"dict": {...}}``.  Anything else is refused.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else {"float": repr(value)}
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in DTYPES:
            raise TypeError(f"an array of dtype {value.dtype} cannot be stored in a checkpoint")
        name = f"a{len(arrays)}"
        arrays[name] = np.ascontiguousarray(value)
        return {"array": name}
    if isinstance(value, list):
        return [encode(v, arrays) for v in value]
    if isinstance(value, tuple):
        return {"tuple": [encode(v, arrays) for v in value]}
    if isinstance(value, Mapping):
        if not all(isinstance(k, str) for k in value):
            raise TypeError(f"a mapping with keys other than strings cannot be stored in a checkpoint: {list(value)}")
        return {"dict": {k: encode(v, arrays) for k, v in value.items()}}
    raise TypeError(f"a {type(value).__name__} cannot be stored in a checkpoint (data only: numbers, strings, "
                    f"arrays, lists, tuples, mappings)")


def decode(value: Any, arrays: Mapping[str, np.ndarray], where: str = "") -> Any:
    """The value :func:`encode` wrote (ValueError for anything it would not have written)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [decode(v, arrays, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, dict) and len(value) == 1:
        (tag, inner), = value.items()
        if tag == "array" and isinstance(inner, str):
            if inner not in arrays:
                raise ValueError(f"{where or 'a value'} refers to the array {inner!r}, which is not in {ARRAYS}")
            return arrays[inner]
        if tag == "float" and inner in ("inf", "-inf", "nan"):
            return float(inner)
        if tag == "tuple" and isinstance(inner, list):
            return tuple(decode(v, arrays, f"{where}[{i}]") for i, v in enumerate(inner))
        if tag == "dict" and isinstance(inner, dict):
            return {k: decode(v, arrays, f"{where}.{k}") for k, v in inner.items()}
    raise ValueError(f"{where or 'a value'} is not a value a checkpoint holds: {str(value)[:80]}")


def _canonical(document: Mapping[str, Any]) -> bytes:
    return json.dumps(document, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


def digest(document: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> str:
    """SHA-256 of the JSON ``document`` (canonical, without its ``sha256``) and of every array (name, dtype,
    shape, bytes; by name)."""
    h = hashlib.sha256(_canonical({k: v for k, v in document.items() if k != "sha256"}))
    for name in sorted(arrays):
        a = arrays[name]
        h.update(f"\0{name}\0{a.dtype.str}\0{list(a.shape)}\0".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


# -- the known types ----------------------------------------------------------------
def _state_data(state: State, setup: Any) -> dict[str, Any]:
    return {
        "n": int(state.n),
        "t": float(state.t),
        "wall": None if state.wall is None else {"d": state.wall.d, "V": state.wall.V},
        "fluid": None if state.fluid is None else setup.fluid.state_to_data(state.fluid),
        "v": state.v,
        "eta": state.eta,
        "extra": dict(state.extra),
        "previous": None if state.previous is None else _state_data(state.previous, setup),
    }


def _array_like(value: Any, template: Any, where: str) -> Any:
    """``value`` when it is None where the template is, or an array of the template's dtype and shape."""
    if template is None:
        if value is not None:
            raise ValueError(f"{where} should be empty (None)")
        return None
    if not isinstance(value, np.ndarray):
        raise ValueError(f"{where} should be an array, not {type(value).__name__}")
    if value.dtype != template.dtype or value.shape != template.shape:
        raise ValueError(f"{where} is a {value.dtype} array of shape {value.shape}, expected {template.dtype} "
                         f"{template.shape}")
    return value


def _state_from_data(data: Any, setup: Any, template: State, where: str = "state") -> State:
    keys = {"n", "t", "wall", "fluid", "v", "eta", "extra", "previous"}
    if not isinstance(data, dict) or set(data) != keys:
        raise ValueError(f"{where} should have the fields {sorted(keys)}")
    if not isinstance(data["n"], int) or isinstance(data["n"], bool) or not isinstance(data["t"], float):
        raise ValueError(f"{where}.n should be a whole number and {where}.t a number")
    wall = None
    if (data["wall"] is None) != (template.wall is None):
        raise ValueError(f"{where}.wall should {'not ' if template.wall is not None else ''}be empty")
    if template.wall is not None:
        if not isinstance(data["wall"], dict) or set(data["wall"]) != {"d", "V"}:
            raise ValueError(f"{where}.wall should have the fields d and V")
        wall = WallState(_array_like(data["wall"]["d"], template.wall.d, f"{where}.wall.d"),
                         _array_like(data["wall"]["V"], template.wall.V, f"{where}.wall.V"))
    fluid = None
    if (data["fluid"] is None) != (template.fluid is None):
        raise ValueError(f"{where}.fluid should {'not ' if template.fluid is not None else ''}be empty")
    if template.fluid is not None:
        fluid = setup.fluid.state_from_data(data["fluid"])
    if not isinstance(data["extra"], dict):
        raise ValueError(f"{where}.extra should be a mapping")
    previous = None
    if data["previous"] is not None:
        previous = _state_from_data(data["previous"], setup, template, f"{where}.previous")
    return State(data["n"], data["t"], wall, fluid, _array_like(data["v"], template.v, f"{where}.v"),
                 _array_like(data["eta"], template.eta, f"{where}.eta"), data["extra"], previous)


def _tally_data(tally: Any, wall_time_s: float) -> dict[str, Any]:
    b = tally.bound
    return {"previous": float(tally.previous),
            "bound": {"initial": float(b.initial), "margin": float(b.margin), "work": float(b.work),
                      "scale": float(b.scale)},
            "steps": int(tally.steps), "t": float(tally.t), "max_rel": float(tally.max_rel),
            "iterations": np.asarray(tally.iterations, dtype=float),
            "peaks": {k: float(v) for k, v in tally.peaks.items()},
            "wall_time_s": float(tally.wall_time_s + wall_time_s),
            "volume": tally.volume.to_data() if tally.volume is not None else None}


def _tally_from_data(data: Any) -> Any:
    from multilayer.runner.stepping import EnergyBound, Tally

    numbers = ("previous", "t", "max_rel", "wall_time_s")
    if not isinstance(data, dict) or set(data) != {*numbers, "bound", "steps", "iterations", "peaks", "volume"}:
        raise ValueError("the tally should have the fields previous, bound, steps, t, max_rel, iterations, peaks, "
                         "wall_time_s, volume")
    if not all(isinstance(data[k], float) for k in numbers) or not isinstance(data["steps"], int):
        raise ValueError("the tally's previous, t, max_rel, wall_time_s should be numbers, its steps a whole number")
    bound = data["bound"]
    if (not isinstance(bound, dict) or set(bound) != {"initial", "margin", "work", "scale"}
            or not all(isinstance(v, float) for v in bound.values())):
        raise ValueError("the tally's energy bound should have the numbers initial, margin, work, scale")
    iterations = data["iterations"]
    if not (isinstance(iterations, np.ndarray) and iterations.dtype == np.float64 and iterations.ndim == 1):
        raise ValueError("the tally's iterations should be a float64 array")
    peaks = data["peaks"]
    if not isinstance(peaks, dict) or not all(isinstance(v, float) for v in peaks.values()):
        raise ValueError("the tally's peaks should map probes to numbers")
    energy = EnergyBound(bound["initial"], bound["margin"])
    energy.work, energy.scale = bound["work"], bound["scale"]
    volume = VolumeLedger.from_data(data["volume"]) if data["volume"] is not None else None
    return Tally(data["previous"], energy, data["steps"], data["t"], data["max_rel"],
                 [float(x) for x in iterations], dict(peaks), data["wall_time_s"], volume=volume)


def _snapshots_from_data(data: Any) -> dict[str, list[tuple[float, str]]]:
    if not isinstance(data, dict):
        raise ValueError("the snapshots should map collections to their entries")
    out = {}
    for name, entries in data.items():
        if name not in ResultsFolder.PARTS or not isinstance(entries, list):
            raise ValueError(f"the snapshots have a collection {name!r}, not {' or '.join(ResultsFolder.PARTS)}")
        for entry in entries:
            if not (isinstance(entry, list) and len(entry) == 2 and isinstance(entry[0], float)
                    and (snapshot := snapshot_of(entry[1])) and snapshot[0] == name):
                raise ValueError(f"the snapshots of {name} have an entry that is not (t, {name}_NNNNNN.vtu)")
        out[name] = [(t, file) for t, file in entries]
    return out


def _solvers(setup: Any) -> list[tuple[str, Any]]:
    """(name, stats) of every system of the run: the coupler's and the fluid's (``fluid``)."""
    return [*setup.solvers.items(), *([("fluid", setup.fluid.stats)] if setup.fluid is not None else [])]


# -- writing and reading ----------------------------------------------------------
def _without_end(resolved: Mapping[str, Any]) -> dict[str, Any]:
    return {**resolved, "time": {k: v for k, v in resolved["time"].items() if k != "end"}}


def save(folder: Path, case: Case, registry: Registry, state: State, tally: Any,
         snapshots: Mapping[str, list], every: int, wall_time_s: float, setup: Any, run: str | None = None) -> Path:
    """Write ``checkpoint.npz`` and ``checkpoint.json`` (each written whole before it replaces the previous one).

    ``setup`` is the run's: its fluid writes its state's data, and its solvers their held states.  ``run`` is
    the identity of the run that owns the folder (:attr:`ResultsFolder.run_id`): only that run resumes from it.
    """
    arrays: dict[str, np.ndarray] = {}
    solvers = [[name, None if stats.solver is None else stats.solver.held()] for name, stats in _solvers(setup)]
    document = {
        "format": MAGIC,
        "version": FORMAT,
        "multilayer_version": __version__,
        "resolved": encode(dict(case.resolved), arrays),
        "base_dir": str(case.base_dir),
        "case_digest": case.digest,
        "plugins": encode(plugin_versions(case, registry), arrays),
        "every": int(every),
        "state": encode(_state_data(state, setup), arrays),
        "tally": encode(_tally_data(tally, wall_time_s), arrays),
        "snapshots": encode({k: [[float(t), str(f)] for t, f in v] for k, v in snapshots.items()}, arrays),
        "solvers": encode([[name, held] for name, held in solvers if held is not None], arrays),
        "run": run,
    }
    document["sha256"] = digest(document, arrays)
    # each written whole to a fresh temporary and renamed into place (never through a symbolic link); a crash
    # between the two leaves a pair whose digest does not match, which resume refuses
    with atomic_file(folder / ARRAYS) as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    with atomic_file(folder / FILE) as f:
        f.write(json.dumps(document, indent=1, ensure_ascii=True, allow_nan=False).encode("ascii"))
        f.flush()
        os.fsync(f.fileno())
    return folder / FILE


def exists(folder: Path) -> bool:
    return (folder / FILE).is_file()


def _not_json(constant: str) -> None:
    raise ValueError(f"{constant} is not JSON")


def _read(folder: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The checked JSON document and arrays of ``folder``'s checkpoint (format, version, dtypes, digest)."""
    path, npz = folder / FILE, folder / ARRAYS
    if not path.is_file():
        if (folder / LEGACY).is_file():
            raise CheckpointError(f"{folder / LEGACY} was written by an older multilayer as a pickle, which is "
                                  f"not read, for safety (unpickling can run any code): rerun the case with "
                                  f"--checkpoint-every N to be able to resume")
        raise CheckpointError(f"{folder} has no {FILE}: run with --checkpoint-every N to be able to resume")
    try:
        size = path.stat().st_size
        if size > MAX_DOCUMENT:  # the arrays are in the npz: the document is the case and the structure
            raise CheckpointError(f"{path} is {size / 2**20:.0f} MiB, more than a checkpoint's document ever is "
                                  f"({MAX_DOCUMENT // 2**20} MiB: its arrays are in {ARRAYS}): not read")
        document = json.loads(path.read_bytes().decode("ascii"), parse_constant=_not_json)
    except (OSError, ValueError) as exc:
        raise CheckpointError(f"{path} cannot be read (not JSON: {exc})") from None
    except RecursionError:
        raise CheckpointError(f"{path} is nested deeper than a checkpoint ever is: not read") from None
    if not isinstance(document, dict) or document.get("format") != MAGIC:
        raise CheckpointError(f"{path} is not a multilayer checkpoint")
    version = document.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise CheckpointError(f"{path} has no format version")
    if version > FORMAT:
        raise CheckpointError(f"{path} has format version {version}, newer than this multilayer's {FORMAT} "
                              f"(multilayer {document.get('multilayer_version')!s:.40} wrote it): resume it with "
                              f"that version")
    if version != FORMAT:
        raise CheckpointError(f"{path} has format version {version}, which this multilayer ({FORMAT}) does not read")
    if not npz.is_file():
        raise CheckpointError(f"{folder} has {FILE} but no {ARRAYS}")
    _arrays_fit(npz)
    try:
        with np.load(npz, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except ValueError as exc:
        if "allow_pickle" in str(exc):
            raise CheckpointError(f"{npz} holds an object array, which is not read, for safety") from None
        raise CheckpointError(f"{npz} cannot be read ({exc})") from None
    except Exception as exc:  # a truncated or foreign file: zipfile, OSError, EOFError...
        raise CheckpointError(f"{npz} cannot be read ({type(exc).__name__}: {exc})") from None
    bad = [name for name, a in arrays.items() if not isinstance(a, np.ndarray) or a.dtype.kind not in DTYPES]
    if bad:
        raise CheckpointError(f"{npz} holds what a checkpoint never writes (not arrays of numbers): "
                              f"{', '.join(bad)[:200]}")
    if not isinstance(document.get("sha256"), str) or document["sha256"] != digest(document, arrays):
        raise CheckpointError(f"{path} and {ARRAYS} do not match their SHA-256 digest: the checkpoint is corrupt "
                              f"(or one of the two files is from another checkpoint)")
    return document, arrays


def _arrays_fit(npz: Path) -> None:
    """Refuse, before reading any array, an npz that would take more memory than its own size on disk.

    A checkpoint's arrays are stored uncompressed (:func:`numpy.savez`), so each member's declared size is
    its size in the file and each array's header (shape × item size) fits in its member: checked here, so that
    a crafted file (a compressed member that inflates, a header that claims a shape of 2⁶⁰) is refused
    instead of exhausting memory.
    """
    try:
        size = npz.stat().st_size
        if size > MAX_ARRAYS:
            raise CheckpointError(f"{npz} is {size:,} bytes, more than a checkpoint's arrays ever are here "
                                  f"({MAX_ARRAYS:,}): not read")
        with zipfile.ZipFile(npz) as archive:
            members = archive.infolist()
            foreign = [m.filename for m in members if not m.filename.endswith(".npy")]
            if foreign:
                raise CheckpointError(f"{npz} holds what a checkpoint never writes (not arrays of numbers): "
                                      f"{', '.join(foreign)[:200]}")
            packed = [m.filename for m in members if m.compress_type != zipfile.ZIP_STORED]
            if packed:
                raise CheckpointError(f"{npz}: {packed[0][:60]!r} is compressed, which a checkpoint never is: "
                                      f"not read")
            if sum(m.file_size for m in members) > size:
                raise CheckpointError(f"{npz} declares more data than it holds: not read")
            for member in members:
                with archive.open(member) as f:
                    version = np.lib.format.read_magic(f)
                    if version not in ((1, 0), (2, 0)):  # what numpy.savez writes
                        raise CheckpointError(f"{npz}: {member.filename[:60]!r} is an array of format {version}, "
                                              f"which a checkpoint never is: not read")
                    read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                        np.lib.format.read_array_header_2_0
                    shape, _, dtype = read_header(f)
                    if math.prod(shape) * dtype.itemsize > member.file_size:
                        raise CheckpointError(f"{npz}: {member.filename[:60]!r} claims {shape} of {dtype}, more "
                                              f"than its {member.file_size:,} bytes: not read")
    except CheckpointError:
        raise
    except Exception as exc:  # not a zip, a header numpy does not read: zipfile, ValueError, OSError...
        raise CheckpointError(f"{npz} cannot be read ({type(exc).__name__}: {str(exc)[:120]})") from None


def load(folder: Path, registry: Registry, until: float | None = None) -> Checkpoint:
    """Read ``folder``'s checkpoint, check it, and rebuild its case (``time.end`` = ``until`` when given).

    Raises :class:`CheckpointError` for anything it refuses (see the module's docstring).
    """
    document, arrays = _read(folder)
    path = folder / FILE
    keys = ("multilayer_version", "resolved", "base_dir", "case_digest", "plugins", "every", "state", "tally",
            "snapshots", "solvers", "run")
    missing = [k for k in keys if k not in document]
    if missing:
        raise CheckpointError(f"{path} lacks {', '.join(missing)}")
    try:
        resolved = decode(document["resolved"], {}, "resolved")
        plugins_then = decode(document["plugins"], {}, "plugins")
        tally = _tally_from_data(decode(document["tally"], arrays, "tally"))
        snapshots = _snapshots_from_data(decode(document["snapshots"], {}, "snapshots"))
        state = decode(document["state"], arrays, "state")
        solvers = decode(document["solvers"], arrays, "solvers")
        if not isinstance(resolved, dict) or not isinstance(resolved.get("time"), dict):
            raise ValueError("the resolved case should be a mapping with a time table")
        if not isinstance(plugins_then, dict):
            raise ValueError("the plugin versions should be a mapping")
        if not isinstance(document["base_dir"], str) or not isinstance(document["case_digest"], str):
            raise ValueError("base_dir and case_digest should be strings")
        if not isinstance(document["every"], int) or document["every"] < 0:
            raise ValueError("every should be a whole number ≥ 0")
        if not isinstance(solvers, list) or not all(
                isinstance(s, list) and len(s) == 2 and isinstance(s[0], str) for s in solvers):
            raise ValueError("the solvers should be a list of (name, held state)")
        for name, held in solvers:
            try:
                _held_check(held)
            except ValueError as exc:
                raise ValueError(f"solver {name!r}: {exc}") from None
        _all_finite(state, "state")
        if not math.isfinite(tally.t):
            raise ValueError(f"the tally's t = {tally.t!r} is not finite")
        _counters_agree(state, tally)
    except (ValueError, TypeError) as exc:
        raise CheckpointError(f"{path} is malformed: {exc}") from None
    except RecursionError:
        raise CheckpointError(f"{path} is nested deeper than a checkpoint ever is: not read") from None
    owner = run_identity(folder)
    if document["run"] is None or document["run"] != owner:
        raise CheckpointError(f"{path} belongs to another run than the one whose results are in {folder} "
                              f"(its run {document['run']!r}, the folder's {owner!r}): not resumed, nothing touched")
    if until is not None:
        if until <= tally.t:
            raise CheckpointError(f"--until {until:g} s is not after the checkpoint's t = {tally.t:g} s")
        resolved["time"] = {**resolved["time"], "end": until}
    try:
        case = validate_data(resolved, document["base_dir"], registry)
    except CaseError as exc:
        raise CheckpointError(f"the checkpoint's case is no longer valid here:\n{exc}") from None
    if _without_end(case.resolved) != _without_end(resolved) or (
            until is None and case.digest != document["case_digest"]):
        raise CheckpointError("the case resolves differently now than when the checkpoint was written "
                              "(plugin defaults changed?): refusing to resume")
    plugins = plugin_versions(case, registry)
    if plugins != plugins_then:
        changed = [f"{k}: {plugins_then.get(k)} → {v}" for k, v in plugins.items() if plugins_then.get(k) != v]
        raise CheckpointError("the plugins differ from the checkpoint's, refusing to resume: " + "; ".join(changed))
    return Checkpoint(case, state, tally, snapshots, int(document["every"]), [tuple(s) for s in solvers])


def _all_finite(value: Any, where: str) -> None:
    """Every number in ``value`` (decoded data: mappings, lists, arrays) finite: a state of NaN resumes nothing."""
    if isinstance(value, dict):
        for k, v in value.items():
            _all_finite(v, f"{where}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _all_finite(v, f"{where}[{i}]")
    elif isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            raise ValueError(f"{where} holds a number that is not finite")
    elif isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{where} is not finite")


def _counters_agree(state: Any, tally: Any) -> None:
    """The state's step and time are the tally's, and each older level one step and some time before."""
    if not isinstance(state, dict):
        raise ValueError("the state should be a mapping")
    if state.get("n") != tally.steps or state.get("t") != tally.t:
        raise ValueError(f"the state is at step {state.get('n')!r}, t = {state.get('t')!r}, its tally at step "
                         f"{tally.steps}, t = {tally.t!r}")
    level = state
    while isinstance(level.get("previous"), dict):
        older = level["previous"]
        if not (isinstance(older.get("n"), int) and isinstance(older.get("t"), float)
                and older["n"] == level["n"] - 1 and older["t"] < level["t"]):
            raise ValueError(f"the state's older level (step {older.get('n')!r}, t = {older.get('t')!r}) is not "
                             f"the step before step {level['n']!r} at t = {level['t']!r}")
        level = older


def _held_check(held: Any) -> None:
    from multilayer.numerics.held import check
    from multilayer.numerics.linsolve import ReusingSolver

    check(held, ReusingSolver.GUESS_SPAN)


def restore(saved: Checkpoint, setup: Any, coupler: Any) -> State:
    """The checkpoint's State, rebuilt on the run's ``setup`` (each field checked against the coupler's initial
    state's type and shape, the fluid's by the fluid); each reusing solver's held state handed to its counters,
    for the solver to take back before its first solve.  Raises :class:`CheckpointError`."""
    template = coupler.initial_state(setup)
    try:
        state = _state_from_data(saved.state, setup, template)
    except (ValueError, TypeError, KeyError) as exc:
        raise CheckpointError(f"the checkpoint's state does not fit this run: {exc}") from None
    if state.n != saved.tally.steps:
        raise CheckpointError(f"the checkpoint's state is at step {state.n}, its tally at {saved.tally.steps}")
    for name, held in saved.solvers:
        if name == "fluid":
            if setup.fluid is None:
                raise CheckpointError("the checkpoint holds a fluid solver, and this run has no fluid")
            stats = setup.fluid.stats
        else:
            stats = setup.stats(name)  # made now as the coupler will ask for it: the same counters
        stats.resume = held
    return state
