"""Checkpoints: the whole state of a run, written atomically, and read back to resume it.

A checkpoint holds the coupler's :class:`~multilayer.scene.state.State` (every
field and every older level a scheme needs), the run's tally (the ledger's
running total, the energy bound, counts), the snapshot collections, and what
the run was: the resolved case (with the folder its table files are read
from), its digest and the plugin versions.  Resuming under other plugin
versions, or a case that resolves differently (only ``time.end`` may move,
with ``--until``), is refused.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs

from multilayer.case.casefile import validate_data
from multilayer.case.model import Case
from multilayer.plugin.problems import CaseError
from multilayer.plugin.registry import Registry, plugin_versions
from multilayer.version import __version__

FILE = "checkpoint.pkl"
FORMAT = 1


class CheckpointError(Exception):
    """No usable checkpoint, or one that does not belong to this case and these plugins."""


@attrs.frozen(eq=False)
class Checkpoint:
    case: Case
    state: Any
    tally: Any
    snapshots: Mapping[str, list]
    checkpoint_every: int


def _without_end(resolved: Mapping[str, Any]) -> dict[str, Any]:
    return {**resolved, "time": {k: v for k, v in resolved["time"].items() if k != "end"}}


def save(folder: Path, case: Case, registry: Registry, state: Any, tally: Any,
         snapshots: Mapping[str, list], every: int, wall_time_s: float) -> Path:
    """Write ``folder/checkpoint.pkl`` atomically (a crash while writing leaves the previous one)."""
    data = {
        "format": FORMAT,
        "multilayer_version": __version__,
        "resolved": dict(case.resolved),
        "base_dir": case.base_dir,
        "digest": case.digest,
        "plugins": plugin_versions(case, registry),
        "state": state,
        "tally": attrs.evolve(tally, wall_time_s=tally.wall_time_s + wall_time_s),
        "snapshots": dict(snapshots),
        "every": every,
    }
    path = folder / FILE
    tmp = path.with_name(FILE + ".tmp")
    with open(tmp, "wb") as f:
        pickle.dump(data, f, protocol=pickle.HIGHEST_PROTOCOL)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def load(folder: Path, registry: Registry, until: float | None = None) -> Checkpoint:
    """Read ``folder/checkpoint.pkl`` and rebuild its case (``time.end`` = ``until`` when given)."""
    path = folder / FILE
    if not path.is_file():
        raise CheckpointError(f"{folder} has no {FILE}: run with --checkpoint-every N to be able to resume")
    try:
        with open(path, "rb") as f:
            data = pickle.load(f)
    except Exception as exc:  # a truncated or foreign file
        raise CheckpointError(f"{path} cannot be read ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a checkpoint of this version of multilayer")
    resolved = dict(data["resolved"])
    if until is not None:
        if until <= data["tally"].t:
            raise CheckpointError(f"--until {until:g} s is not after the checkpoint's t = {data['tally'].t:g} s")
        resolved["time"] = {**resolved["time"], "end": until}
    try:
        case = validate_data(resolved, data["base_dir"], registry)
    except CaseError as exc:
        raise CheckpointError(f"the checkpoint's case is no longer valid here:\n{exc}") from None
    if _without_end(case.resolved) != _without_end(resolved) or (until is None and case.digest != data["digest"]):
        raise CheckpointError("the case resolves differently now than when the checkpoint was written "
                              "(plugin defaults changed?): refusing to resume")
    plugins = plugin_versions(case, registry)
    if plugins != data["plugins"]:
        changed = [f"{k}: {data['plugins'].get(k)} → {v}" for k, v in plugins.items() if data["plugins"].get(k) != v]
        raise CheckpointError("the plugins differ from the checkpoint's, refusing to resume: " + "; ".join(changed))
    return Checkpoint(case, data["state"], data["tally"], data["snapshots"], int(data["every"]))
