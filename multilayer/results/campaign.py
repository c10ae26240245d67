"""The ``--out`` folder of a campaign (``compare``, ``study``, ``stability``, ``sweep``): it owns only what it wrote.

A campaign folder holds one results folder per run (each a
:class:`~multilayer.results.folder.ResultsFolder`, with its own manifest and
lock) and the campaign's reports and figures.  Like a run's folder it keeps
a ``manifest.json`` (its own format, :data:`FORMAT`, so a run refuses it and
it refuses a run's folder) listing the reports it wrote: a campaign run
again into it rewrites those and nothing else.  :func:`open_campaign`
refuses, before any run starts, the current directory, ``/``, home, a
non-empty folder that is not a campaign folder of multilayer (unless
``force``), a report name held by a file the campaign did not write, a
manifest that lists anything but a report file directly inside the folder,
and a run folder that is a link (or lies under one) inside the campaign's:
a folder that users copy and share cannot lead a campaign to write or remove
anything outside it.  :func:`claim` names a report file and lists it before
it is written.
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Iterable
from pathlib import Path

from multilayer.results.files import ResultsError, write_atomically
from multilayer.results.folder import MANIFEST, dangerous, read_manifest

#: what a campaign folder's ``manifest.json`` says it is
FORMAT = "multilayer campaign folder"

#: the name of a report or figure a campaign writes directly inside its folder
REPORT = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_=.,+-]*\.(json|md|png|csv)")


def campaign_files(folder: Path) -> frozenset[str] | None:
    """The names of the files a campaign owns in ``folder`` (its manifest's list); None: not a campaign folder.

    Raises
    ------
    ResultsError
        The manifest lists something a campaign never writes (a path, a link out of the folder, a name of
        another kind): it is data the folder carries, not a list of what a campaign may overwrite.
    """
    manifest = read_manifest(folder)
    if isinstance(manifest, dict) and manifest.get("format") == FORMAT and isinstance(manifest.get("files"), list):
        listed = manifest["files"]
        strangers = [name for name in listed if not (isinstance(name, str) and REPORT.fullmatch(name))]
        if strangers:
            raise ResultsError(f"{Path(folder) / MANIFEST} lists {strangers[0]!r}"
                               f"{f' and {len(strangers) - 1} more' if len(strangers) > 1 else ''}, not a report a "
                               f"campaign of multilayer writes in its folder: refused, nothing touched (a campaign "
                               f"owns only its reports and figures, <name>.json|md|png|csv directly inside the folder)")
        return frozenset(listed)
    return None


def _refuse_what_is_not_a_file(out: Path, owned: Iterable[str]) -> None:
    """A listed report that is now a folder (or a device, a pipe) is refused before anything is written."""
    for name in sorted(owned):
        try:
            mode = os.lstat(out / name).st_mode
        except FileNotFoundError:
            continue
        except OSError as exc:
            raise ResultsError(f"cannot read {out / name}: {exc.strerror or exc}") from None
        if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):  # a link is replaced, never followed
            raise ResultsError(f"{out / name} is not a file: not a report of the campaign, not overwritten")


def _refuse_links_to_runs(out: Path, runs: Iterable[str]) -> None:
    """A run's folder inside the campaign (``<label>`` or ``runs/<digest>``) must be a folder here, not a link."""
    for run in runs:
        path = out
        for part in Path(run).parts:
            path = path / part
            if path.is_symlink():
                raise ResultsError(f"{path} is a link: a campaign writes its runs only in folders of its own "
                                   f"inside {out}; remove the link or choose another --out")
            if os.path.lexists(path) and not path.is_dir():
                raise ResultsError(f"{path} is a file, not a run's folder: move it away or choose another --out")


def _write(folder: Path, files: Iterable[str]) -> None:
    try:
        write_atomically(folder / MANIFEST, json.dumps({"format": FORMAT, "files": sorted(files)}, indent=1) + "\n")
    except OSError as exc:
        raise ResultsError(f"cannot write in {folder}: {exc.strerror or exc}") from None


def open_campaign(out: Path, reports: Iterable[str], force: bool = False, runs: Iterable[str] = ()) -> Path:
    """Make (or take up again) the campaign folder ``out`` that will hold ``reports`` and the run folders ``runs``
    (relative to ``out``); ResultsError if it cannot, before anything is written.

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
    _refuse_what_is_not_a_file(out, owned)
    _refuse_links_to_runs(out, runs)
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
