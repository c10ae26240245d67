"""The ``--out`` folder of a campaign (``compare``, ``study``, ``stability``, ``sweep``): it owns only what it wrote.

A campaign folder holds one results folder per run (each a
:class:`~multilayer.results.folder.ResultsFolder`, with its own manifest and
lock) and the campaign's reports and figures.  Like a run's folder it keeps
a ``manifest.json`` (its own format, :data:`FORMAT`, so a run refuses it and
it refuses a run's folder) listing the reports it wrote: a campaign run
again into it rewrites those and nothing else.  :func:`open_campaign`
refuses, before any run starts, the current directory, ``/``, home, a
non-empty folder that is not a campaign folder of multilayer (unless
``force``), and a report name held by a file the campaign did not write;
:func:`claim` names a report file and lists it before it is written.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path

from multilayer.results.files import ResultsError, write_atomically
from multilayer.results.folder import MANIFEST, dangerous, read_manifest

#: what a campaign folder's ``manifest.json`` says it is
FORMAT = "multilayer campaign folder"


def campaign_files(folder: Path) -> frozenset[str] | None:
    """The names of the files a campaign owns in ``folder`` (its manifest's list); None: not a campaign folder."""
    manifest = read_manifest(folder)
    if isinstance(manifest, dict) and manifest.get("format") == FORMAT and isinstance(manifest.get("files"), list):
        return frozenset(str(name) for name in manifest["files"])
    return None


def _write(folder: Path, files: Iterable[str]) -> None:
    try:
        write_atomically(folder / MANIFEST, json.dumps({"format": FORMAT, "files": sorted(files)}, indent=1) + "\n")
    except OSError as exc:
        raise ResultsError(f"cannot write in {folder}: {exc.strerror or exc}") from None


def open_campaign(out: Path, reports: Iterable[str], force: bool = False) -> Path:
    """Make (or take up again) the campaign folder ``out`` that will hold ``reports``; ResultsError if it cannot.

    ``force``: write into the current directory, home or a non-empty
    folder that is not a campaign folder — still only the campaign's own
    files (a report name already held by another file is refused all the same).
    """
    out = Path(out)
    if not force and (why := dangerous(out)):
        raise ResultsError(f"--out {out} {why}: choose a folder of its own (or --force)")
    if out.exists() and not out.is_dir():
        raise ResultsError(f"--out {out} is a file, not a folder")
    owned = campaign_files(out) if out.is_dir() else frozenset()
    if owned is None:
        if not force and any(out.iterdir()):
            raise ResultsError(f"--out {out} is not empty and not a campaign folder of multilayer (no {MANIFEST} "
                               f"of one): choose another --out, or --force to write into it (the campaign touches "
                               f"only its own files)")
        if os.path.lexists(out / MANIFEST):
            raise ResultsError(f"{out / MANIFEST} was not written by a campaign of multilayer: not overwritten")
        owned = frozenset()
    clash = sorted(name for name in reports if name not in owned and os.path.lexists(out / name))
    if clash:
        raise ResultsError(f"{out} holds {', '.join(clash)} that no campaign of multilayer wrote there: move it "
                           f"away or choose another --out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ResultsError(f"cannot create {out}: {exc.strerror or exc}") from None
    _write(out, owned)
    return out


def claim(out: Path, name: str) -> Path:
    """``out / name``, listed in the campaign's manifest; ResultsError when a file of that name is not the campaign's."""
    owned = campaign_files(out) or frozenset()
    if name not in owned:
        if os.path.lexists(out / name):
            raise ResultsError(f"{out / name} was not written by a campaign of multilayer: not overwritten")
        _write(out, owned | {name})
    return out / name
