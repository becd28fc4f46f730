"""The Python engine against `sweptccd query` / `sweptccd world` on the
bundled data, record for record; bad input raises and disturbs nothing."""

from __future__ import annotations

import dataclasses
import json
import threading
import time
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import pytest

import sweptccd
from conftest import APARTMENT, cli_records, run_cli

IGNORED = ("elapsed_us", "stats")


def strip(record: Dict[str, Any]) -> Dict[str, Any]:
    out = {k: v for k, v in record.items() if k not in IGNORED}
    if "others" in out:
        out["others"] = [{k: v for k, v in o.items() if k not in IGNORED} for o in out["others"]]
    return out


def fields_present(rec: sweptccd.Record) -> Dict[str, Any]:
    """The record's SPEC fields that are set (None means absent)."""
    d = {f.name: getattr(rec, f.name) for f in dataclasses.fields(rec) if f.name != "extra"}
    return {k: v for k, v in d.items() if v is not None}


def assert_same(py: List[sweptccd.Record], py_json: List[str], cli: List[Dict[str, Any]]) -> None:
    assert len(py) == len(cli) == len(py_json)
    for rec, line, ref in zip(py, py_json, cli):
        assert strip(json.loads(line)) == strip(ref)
        # Every field of the command's record is a dataclass field or in extra.
        assert set(fields_present(rec)) | set(rec.extra) == set(ref)
        # And the dataclass holds the same values as the command's record.
        ref_rec = sweptccd.Record.from_json(json.dumps(ref))
        assert dataclasses.replace(rec, extra={}) == dataclasses.replace(ref_rec, extra={})


@pytest.mark.parametrize("per_link", [False, True])
def test_query_equals_command(walk: Dict[str, Any], per_link: bool) -> None:
    args = ["query", "--skeleton", str(walk["skeleton"]), "--poses", str(walk["poses"]),
            "--env", APARTMENT] + (["--per-link"] if per_link else [])
    cli = cli_records(*args)
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT], per_link=per_link)
    py_json = engine.query_json(walk["utimes"], walk["array"])
    py = engine.query(walk["utimes"], walk["array"])
    assert_same(py, py_json, cli)
    kinds = {r.result for r in py}
    assert kinds == {"free", "contact", "invalid"}, kinds  # The data exercises all three.


def test_ignore_rules_and_independent_motion(walk: Dict[str, Any]) -> None:
    cli = cli_records("query", "--skeleton", str(walk["skeleton"]), "--poses", str(walk["poses"]),
                      "--env", APARTMENT, "--motion", "independent", "--eps", "1e-3",
                      "--ignore", "*:0")
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT], motion="independent", eps=1e-3,
                             ignore=["*:0"])
    py = engine.query(walk["utimes"], walk["array"])
    assert_same(py, engine.query_json(walk["utimes"], walk["array"]), cli)
    assert all(r.result != "contact" for r in py)  # Everything ignored.


def test_work_limit_gives_the_commands_undecided_records(walk: Dict[str, Any]) -> None:
    cli = cli_records("query", "--skeleton", str(walk["skeleton"]), "--poses", str(walk["poses"]),
                      "--env", APARTMENT, "--max-intervals", "3", "--per-link")
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT], max_intervals=3, per_link=True)
    py = engine.query(walk["utimes"], walk["array"])
    assert_same(py, engine.query_json(walk["utimes"], walk["array"]), cli)
    assert any(r.undecided for r in py)
    expected = cli_error("query", "--poses", str(walk["poses"]), "--skeleton",
                         str(walk["skeleton"]), "--env", APARTMENT, "--max-intervals", "0")
    with pytest.raises(sweptccd.InputError) as info:
        sweptccd.Engine(walk["skeleton"], [APARTMENT], max_intervals=0)
    assert str(info.value) == expected


def test_skeleton_dict_equals_file(walk: Dict[str, Any]) -> None:
    doc = json.loads(Path(walk["skeleton"]).read_text())
    a = sweptccd.Engine(walk["skeleton"], [APARTMENT]).query_json(walk["utimes"], walk["array"])
    b = sweptccd.Engine(doc, [APARTMENT]).query_json(walk["utimes"], walk["array"])
    assert [strip(json.loads(x)) for x in a] == [strip(json.loads(y)) for y in b]


@pytest.mark.parametrize("per_link", [False, True])
def test_world_equals_command(world_file: Path, per_link: bool) -> None:
    cli = cli_records("world", "--world", str(world_file), *(["--per-link"] if per_link else []))
    world = sweptccd.World(world_file, per_link=per_link)
    assert world.avatar_ids == ["alice", "bob"]
    py_json = world.records_json()
    py = world.records()
    assert_same(py, py_json, cli)
    others = [o for r in py for o in (r.others or [])]
    assert {o.kind for o in others} == {"avatar", "object"}
    assert any(o.result == "contact" for o in others)


def test_nan_row_is_an_invalid_record(walk: Dict[str, Any]) -> None:
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    before = engine.query_json(walk["utimes"], walk["array"])
    poses = walk["array"].copy()
    poses[30, 2, 4] = np.nan
    recs = engine.query(walk["utimes"], poses)
    assert recs[29].result == "invalid"
    assert recs[29].error == "invalid pose: line 31: link 2: non-finite number"
    # The next valid row pairs with row 29, as after any invalid line.
    assert recs[30].utime0 == int(walk["utimes"][29])
    # Nothing else changed, and the engine answers as before afterwards.
    after = engine.query_json(walk["utimes"], walk["array"])
    assert [strip(json.loads(x)) for x in after] == [strip(json.loads(x)) for x in before]
    same = [i for i in range(len(recs)) if i not in (29, 30)]
    for i in same:
        assert strip(json.loads(before[i])) == strip(json.loads(engine.query_json(
            walk["utimes"], poses)[i]))


@pytest.mark.parametrize("bad", [
    lambda u, p: (u, p[:, :-1, :]),          # One link short.
    lambda u, p: (u, p[:, :, :6]),           # Six numbers per link.
    lambda u, p: (u, p[0]),                  # Two dimensions.
    lambda u, p: (u[:-1], p),                # Utimes shorter than poses.
    lambda u, p: (u.reshape(-1, 1), p),      # Utimes not one-dimensional.
])
def test_wrong_shapes_raise_and_disturb_nothing(walk: Dict[str, Any], bad: Any) -> None:
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    before = engine.query_json(walk["utimes"], walk["array"])
    u, p = bad(walk["utimes"], walk["array"])
    with pytest.raises(ValueError, match=r"must have shape"):
        engine.query(u, p)
    with pytest.raises(ValueError):
        engine.separations(walk["array"][:, :-1, :])
    after = engine.query_json(walk["utimes"], walk["array"])
    assert [strip(json.loads(x)) for x in after] == [strip(json.loads(x)) for x in before]


def test_wrong_types_raise(walk: Dict[str, Any]) -> None:
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    with pytest.raises(TypeError):
        engine.query(walk["utimes"] + 0.5, walk["array"])
    with pytest.raises(TypeError):
        engine.query(walk["utimes"], walk["array"].astype(str))
    # Integral floats are utimes, as 1000000.0 is in a pose file.
    a = engine.query_json(walk["utimes"].astype(np.float64), walk["array"])
    b = engine.query_json(walk["utimes"], walk["array"])
    assert [strip(json.loads(x)) for x in a] == [strip(json.loads(x)) for x in b]


def cli_error(*args: str) -> str:
    r = run_cli(*args)
    assert r.returncode == 2
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("error: ")
    return line[len("error: "):]


def test_missing_files_same_message_as_command(walk: Dict[str, Any], tmp_path: Path) -> None:
    missing = str(tmp_path / "nope.json")
    cases = [
        ((missing, [APARTMENT]), ["--skeleton", missing, "--env", APARTMENT]),
        ((walk["skeleton"], [str(tmp_path / "nope.ply")]),
         ["--skeleton", str(walk["skeleton"]), "--env", str(tmp_path / "nope.ply")]),
    ]
    for (skel, env), flags in cases:
        expected = cli_error("query", "--poses", str(walk["poses"]), *flags)
        with pytest.raises(sweptccd.InputError) as info:
            sweptccd.Engine(skel, env)
        assert str(info.value) == expected
    expected = cli_error("query", "--poses", str(walk["poses"]), "--skeleton",
                         str(walk["skeleton"]), "--env", APARTMENT, "--ignore", "nosuchlink:0")
    with pytest.raises(sweptccd.InputError) as info:
        sweptccd.Engine(walk["skeleton"], [APARTMENT], ignore=["nosuchlink:0"])
    assert str(info.value) == expected
    with pytest.raises(sweptccd.InputError, match=r"^sweptccd query: give at least one --env$"):
        sweptccd.Engine(walk["skeleton"], [])
    expected = cli_error("world", "--world", missing)
    with pytest.raises(sweptccd.InputError) as info:
        sweptccd.World(missing)
    assert str(info.value) == expected


def test_bad_skeleton_and_options_same_message(walk: Dict[str, Any], tmp_path: Path) -> None:
    doc = json.loads(Path(walk["skeleton"]).read_text())
    doc["links"][3]["radius"] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    expected = cli_error("query", "--poses", str(walk["poses"]), "--skeleton", str(bad), "--env",
                         APARTMENT)
    with pytest.raises(sweptccd.InputError) as info:
        sweptccd.Engine(bad, [APARTMENT])
    assert str(info.value) == expected
    # From a dict: the same words after the source's name.
    with pytest.raises(sweptccd.InputError) as info:
        sweptccd.Engine(doc, [APARTMENT])
    assert str(info.value).split(":", 1)[1] == expected.split(":", 1)[1]
    for flag, kw in [("--eps", {"eps": float("nan")}), ("--delta", {"delta": -1.0})]:
        value = str(next(iter(kw.values())))
        expected = cli_error("query", "--poses", str(walk["poses"]), "--skeleton",
                             str(walk["skeleton"]), "--env", APARTMENT, f"{flag}={value}")
        with pytest.raises(sweptccd.InputError) as info:
            sweptccd.Engine(walk["skeleton"], [APARTMENT], **kw)  # type: ignore[arg-type]
        assert str(info.value) == expected


def test_threads_share_one_engine(walk: Dict[str, Any]) -> None:
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    expected = [strip(json.loads(x)) for x in engine.query_json(walk["utimes"], walk["array"])]
    results: List[List[Dict[str, Any]]] = []
    lock = threading.Lock()

    def work() -> None:
        got = [strip(json.loads(x)) for x in engine.query_json(walk["utimes"], walk["array"])]
        with lock:
            results.append(got)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(results) == 4 and all(r == expected for r in results)


def test_gil_released_during_query(walk: Dict[str, Any]) -> None:
    """While one thread is inside a long query, another keeps running Python:
    with the GIL held, its longest pause would be the whole query."""
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    reps = 200  # The clip again and again, later each time: a long stream.
    span = int(walk["utimes"][-1] - walk["utimes"][0]) + 33333
    utimes = np.concatenate([walk["utimes"] + k * span for k in range(reps)])
    poses = np.concatenate([walk["array"]] * reps)
    done = threading.Event()
    took: List[float] = []

    def work() -> None:
        t0 = time.perf_counter()
        engine.query_json(utimes, poses)
        took.append(time.perf_counter() - t0)
        done.set()

    worker = threading.Thread(target=work)
    last = time.perf_counter()
    longest = 0.0
    worker.start()
    while not done.is_set():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    worker.join()
    assert took[0] > 0.05, f"the query was too short to tell ({took[0]:.3f} s)"
    assert longest < 0.5 * took[0], (longest, took[0])


def test_separations_agree_with_answers(walk: Dict[str, Any]) -> None:
    engine = sweptccd.Engine(walk["skeleton"], [APARTMENT])
    sep = engine.separations(walk["array"], search_radius=0.5)
    assert sep.shape == (len(walk["utimes"]), engine.num_links)
    assert np.isnan(sep[7]).all()  # The zero-quaternion row.
    assert np.isnan(sep[20]).all()  # The row past 1e9 m.
    recs = engine.query(walk["utimes"], walk["array"])
    checked = 0
    for r in recs:
        if r.result == "invalid":
            continue
        i0 = int(np.nonzero(walk["utimes"] == r.utime0)[0][0])
        if r.result == "free":  # Free: no link touches at either end.
            assert (sep[i0] > 0).all()
            checked += 1
        elif r.initially_colliding:
            assert sep[i0].min() <= 0
            checked += 1
        else:  # A contact after the start: the witness link is within delta then.
            assert (sep[i0] > 0).all()
            assert r.contacts and min(c.separation for c in r.contacts) <= 1e-3
            checked += 1
    assert checked > 20
