"""A checkpoint is data: nothing in it is unpickled or evaluated, and resume refuses what is not a sound one.

Each refusal is ``multilayer resume`` exiting 2 with a one-line message and no traceback.
"""

import io
import json
import os
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
from runs import CASES

from multilayer.commands.main import main
from multilayer.runner import checkpoint

SMALL = ["mesh.nz=8", "mesh.nr=2", "output.every=0", "time.end=0.001"]


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    """A results folder with a sound checkpoint (10 steps, one every 5)."""
    out = tmp_path_factory.mktemp("ckpt") / "good"
    a = ["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out), "--quiet", "--no-plots",
         "--checkpoint-every", "5"]
    for s in SMALL:
        a += ["--set", s]
    assert main(a) == 0
    return out


def copy(good: Path, to: Path) -> Path:
    to.mkdir()
    for p in good.iterdir():
        if p.is_file() and p.name != ".lock":
            (to / p.name).write_bytes(p.read_bytes())
    return to


def refused(out: Path, capsys, *words: str) -> str:
    before = (out / "summary.json").read_bytes() if (out / "summary.json").exists() else None
    assert main(["resume", str(out), "--quiet", "--no-plots", "--until", "0.002"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    for word in words:
        assert word in err, err
    if before is not None:  # refused before the folder is touched
        assert (out / "summary.json").read_bytes() == before
    return err


def arrays(out: Path) -> dict[str, np.ndarray]:
    with np.load(out / checkpoint.ARRAYS, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def rewrite(out: Path, document: dict, data: dict[str, np.ndarray], sign: bool = True) -> None:
    """Write ``document`` and ``data`` as the folder's checkpoint, its digest recomputed (``sign``): a file a
    buggy or malicious writer made consistent, which the other checks must catch."""
    if sign:
        document = {**document, "sha256": checkpoint.digest(document, data)}
    with open(out / checkpoint.ARRAYS, "wb") as f:
        np.savez(f, **data)
    (out / checkpoint.FILE).write_text(json.dumps(document))


def test_a_sound_checkpoint_resumes(good, tmp_path):
    out = copy(good, tmp_path / "ok")
    assert main(["resume", str(out), "--quiet", "--no-plots", "--until", "0.002"]) == 0
    assert json.loads((out / "summary.json").read_text())["steps"] == 20


class Payload:
    """Unpickling this would create ``path``: what a hostile checkpoint.pkl does."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return (open, (self.path, "w"))


def test_an_old_pickle_is_never_unpickled(tmp_path, capsys):
    out = tmp_path / "old"
    out.mkdir()
    witness = tmp_path / "pwned"
    (out / "checkpoint.pkl").write_bytes(pickle.dumps({"format": 1, "state": Payload(witness)}))
    refused(out, capsys, "checkpoint.pkl", "not read, for safety")
    assert not witness.exists()
    pickle.loads((out / "checkpoint.pkl").read_bytes())  # the payload is live: it would have been created
    assert witness.exists()


def test_a_pickle_beside_a_sound_checkpoint_is_ignored(good, tmp_path):
    out = copy(good, tmp_path / "both")
    witness = tmp_path / "pwned"
    (out / "checkpoint.pkl").write_bytes(pickle.dumps(Payload(witness)))
    assert main(["resume", str(out), "--quiet", "--no-plots", "--until", "0.002"]) == 0
    assert not witness.exists()


def test_an_object_array_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "object")
    data = arrays(out)
    name = next(iter(data))
    data[name] = np.array([Payload(tmp_path / "pwned"), 1.0], dtype=object)
    with open(out / checkpoint.ARRAYS, "wb") as f:
        np.savez(f, **data)  # (np.savez pickles the object array; np.load with allow_pickle=False refuses it)
    refused(out, capsys, "object array", "not read, for safety")
    assert not (tmp_path / "pwned").exists()


def test_one_flipped_bit_in_an_array_is_detected(good, tmp_path, capsys):
    out = copy(good, tmp_path / "bit")
    data = arrays(out)
    name = max(data, key=lambda k: data[k].size)  # the largest array: a field of the state or a solver's matrix
    flipped = data[name].copy()
    flipped.view(np.uint8)[flipped.nbytes // 2] ^= 0x10
    data[name] = flipped
    document = json.loads((out / checkpoint.FILE).read_text())
    rewrite(out, document, data, sign=False)  # the old digest kept: as a flipped bit on disk
    refused(out, capsys, "SHA-256", "corrupt")


def test_a_changed_json_value_is_detected(good, tmp_path, capsys):
    out = copy(good, tmp_path / "json")
    document = json.loads((out / checkpoint.FILE).read_text())
    document["tally"]["dict"]["max_rel"] = 0.5
    (out / checkpoint.FILE).write_text(json.dumps(document))
    refused(out, capsys, "SHA-256")


def test_a_truncated_npz_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "truncated")
    raw = (out / checkpoint.ARRAYS).read_bytes()
    (out / checkpoint.ARRAYS).write_bytes(raw[: len(raw) // 2])
    refused(out, capsys, "checkpoint.npz cannot be read")


def test_json_that_is_not_an_object_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "list")
    (out / checkpoint.FILE).write_text("[1, 2, 3]")
    refused(out, capsys, "not a multilayer checkpoint")


def test_a_missing_key_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "missing")
    document = json.loads((out / checkpoint.FILE).read_text())
    del document["tally"]
    rewrite(out, document, arrays(out))
    refused(out, capsys, "lacks tally")


def test_a_field_of_the_wrong_shape_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "shape")
    document = json.loads((out / checkpoint.FILE).read_text())
    data = arrays(out)
    name = document["state"]["dict"]["wall"]["dict"]["d"]["array"]
    data[name] = data[name][:-1]
    rewrite(out, document, data)
    refused(out, capsys, "state.wall.d", "shape")


def test_a_solver_matrix_out_of_range_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "csr")
    document = json.loads((out / checkpoint.FILE).read_text())
    solvers = document["solvers"]
    assert solvers, "the pulse case's fluid holds factors"
    matrix = solvers[0][1]["dict"]["matrix"]["dict"]
    data = arrays(out)
    indices = data[matrix["indices"]["array"]].copy()
    indices[0] = 10**6  # SuperLU would read out of bounds
    data[matrix["indices"]["array"]] = indices
    rewrite(out, document, data)
    refused(out, capsys, "malformed", "out of range")


def test_a_newer_format_or_a_foreign_file_is_refused(good, tmp_path, capsys):
    out = copy(good, tmp_path / "newer")
    document = json.loads((out / checkpoint.FILE).read_text())
    rewrite(out, {**document, "version": checkpoint.FORMAT + 1}, arrays(out))
    refused(out, capsys, "newer than this multilayer's")
    rewrite(out, {**document, "format": "something-else"}, arrays(out))
    refused(out, capsys, "not a multilayer checkpoint")
    (out / checkpoint.FILE).write_text('{"format": "multilayer-checkpoint", "version": NaN}')
    refused(out, capsys, "cannot be read")
    (out / checkpoint.FILE).write_text(json.dumps(document))
    with zipfile.ZipFile(out / checkpoint.ARRAYS, "w") as z:  # a zip, but not the arrays
        z.writestr("readme.txt", "hello")
    refused(out, capsys, "not arrays of numbers")
    os.unlink(out / checkpoint.ARRAYS)
    refused(out, capsys, "no checkpoint.npz")


def test_values_a_checkpoint_cannot_hold_are_refused_when_written():
    with pytest.raises(TypeError, match="cannot be stored"):
        checkpoint.encode({"x": object()}, {})
    with pytest.raises(TypeError, match="dtype object"):
        checkpoint.encode(np.array([None]), {})
    value = {"a": (1, 2.5, float("inf"), [np.arange(3.0), None, "s"]), "b": True}
    data: dict = {}
    again = checkpoint.decode(json.loads(json.dumps(checkpoint.encode(value, data), allow_nan=False)), data)
    assert again["a"][:2] == (1, 2.5) and again["a"][2] == float("inf") and again["b"] is True
    assert np.array_equal(again["a"][3][0], np.arange(3.0)) and again["a"][3][1:] == [None, "s"]


def run_into(out: Path, *sets: str) -> Path:
    a = ["run", str(CASES / "pulse-koiter-thick.toml"), "--out", str(out), "--quiet", "--no-plots",
         "--checkpoint-every", "5"]
    for s in (*SMALL, *sets):
        a += ["--set", s]
    assert main(a) == 0
    return out


@pytest.mark.parametrize("other", [(), ("time.dt=5e-5",)], ids=["same-case", "another-case"])
def test_a_checkpoint_of_another_run_is_refused_and_the_folder_unchanged(good, tmp_path, capsys, other):
    """Issue 36: a checkpoint carries the identity of the run that owns its folder; one copied in from another
    run (of the same case or not) would append that run's rows to this folder's series."""
    out = copy(good, tmp_path / "mine")
    theirs = run_into(tmp_path / "theirs", *other)
    for name in (checkpoint.FILE, checkpoint.ARRAYS):
        (out / name).write_bytes((theirs / name).read_bytes())
    series = (out / "series.csv").read_bytes()
    refused(out, capsys, "belongs to another run")
    assert (out / "series.csv").read_bytes() == series


@pytest.mark.parametrize("edit, words", [
    ("counter", "its tally at step"),
    ("level", "is not the step before"),
    ("nan", "not finite"),
    ("inf", "not finite"),
])
def test_a_hand_edited_checkpoint_with_its_digest_recomputed_is_refused(good, tmp_path, capsys, edit, words):
    """A consistent state is checked, not only a digest a user can recompute: the step counter against the
    state's, each older level one step before, every number finite."""
    out = copy(good, tmp_path / edit)
    document = json.loads((out / checkpoint.FILE).read_text())
    document.pop("sha256")
    data = arrays(out)
    if edit == "counter":
        document["tally"]["dict"]["steps"] += 1
    elif edit == "level":
        document["state"]["dict"]["previous"]["dict"]["n"] -= 1
    elif edit == "inf":
        document["tally"]["dict"]["t"] = {"float": "inf"}
    else:
        key = next(k for k, v in data.items() if v.dtype.kind == "f" and v.size)
        data[key] = data[key].copy()
        data[key].flat[0] = np.nan
    rewrite(out, document, data)
    refused(out, capsys, *words.split("|"))


@pytest.mark.parametrize("kind, words", [("deep", "nested deeper"), ("huge", "MiB, more than a checkpoint's")])
def test_a_checkpoint_document_too_deep_or_too_large_ends_in_one_line(good, tmp_path, capsys, kind, words):
    out = copy(good, tmp_path / kind)
    if kind == "deep":
        nested = "0"
        for _ in range(5000):
            nested = f"[{nested}]"
        text = (out / checkpoint.FILE).read_text()
        (out / checkpoint.FILE).write_text(text[:-1] + f', "deep": {nested}}}')
    else:  # a sparse file: its size is read, never its content
        with open(out / checkpoint.FILE, "r+b") as f:
            f.truncate(checkpoint.MAX_DOCUMENT + 1)
    refused(out, capsys, words)


@pytest.mark.parametrize("kind, words", [("compressed", "is compressed"), ("claims", "claims"),
                                         ("huge", "more than a checkpoint's arrays")])
def test_arrays_that_would_take_more_memory_than_their_file_are_refused_before_reading(good, tmp_path, capsys,
                                                                                        kind, words):
    """Issue 36: readers bound every size they read; an npz is read only as large as it is on disk."""
    out = copy(good, tmp_path / kind)
    data = arrays(out)
    if kind == "compressed":  # a member that inflates (a zip bomb is one of these)
        with open(out / checkpoint.ARRAYS, "wb") as f:
            np.savez_compressed(f, **data)
    elif kind == "claims":  # a header that claims a shape of 2⁴⁰ over the bytes of a small array
        name = max(data, key=lambda k: data[k].size)
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (2**40,)})
        with zipfile.ZipFile(out / checkpoint.ARRAYS, "w") as archive:  # stored, as np.savez writes
            for key, value in data.items():
                member = io.BytesIO()
                np.lib.format.write_array(member, value)
                raw = header.getvalue() + data[name].tobytes() if key == name else member.getvalue()
                archive.writestr(f"{key}.npy", raw)
    else:  # a sparse file: its size is read, never its content
        with open(out / checkpoint.ARRAYS, "r+b") as f:
            f.truncate(checkpoint.MAX_ARRAYS + 1)
    refused(out, capsys, words)
