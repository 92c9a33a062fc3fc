"""``python -m neuroimagery.experiments.exp5.world``: several seeds pooled, each library kept as it
is done and reused by a rerun with the same settings (a stand-in library, no physics)."""
import json

import pytest

from neuroimagery.experiments.exp5 import world as exp5_world


def fake_library(seed, i, table_contact="lift"):
    """A library whose pull retrieves from posture 4 for odd ``i`` only, with a route for seed 1."""
    return dict(library=i, skills={"retrieve": [True, True, False, bool(i % 2)], "touch": [False, True, True, True]},
                events_seen=[[1, 0, 1, 0, 1, 0]] * 4, missing=[], has_pull=True,
                pull_alone_from_4=bool(i % 2), move_then_pull_from_4=["touch"] if seed == 1 else [], rollouts=1)


def run(tmp_path, *extra):
    return exp5_world.main(["--libraries", "2", "--seed", "0", "1", "--jobs", "1", "--out", str(tmp_path), *extra])


def test_seeds_are_pooled_and_listed(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(exp5_world, "_one_library", fake_library)
    assert run(tmp_path) == 0
    out = json.loads((tmp_path / "world_libraries.json").read_text())
    assert out["summary"]["libraries"] == 4
    assert out["summary"]["pull_alone_from_4"] == 2 and out["summary"]["move_then_pull"] == 2
    assert [(r["seed"], r["pull_alone_from_4"], r["move_then_pull"]) for r in out["per_seed"]] == [(0, 1, 0), (1, 1, 2)]
    assert sorted((lib["seed"], lib["library"]) for lib in out["libraries"]) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert "| 1 | 2 |" in (tmp_path / "world_libraries.md").read_text()
    assert len(list((tmp_path / "libraries").glob("*.json"))) == 4


def test_a_rerun_reuses_the_kept_libraries_and_redoes_changed_ones(tmp_path, monkeypatch):
    monkeypatch.setattr(exp5_world, "_one_library", fake_library)
    assert run(tmp_path) == 0
    first = (tmp_path / "world_libraries.json").read_text()
    calls = []

    def counted(seed, i, table_contact="lift"):
        calls.append((seed, i, table_contact))
        return fake_library(seed, i, table_contact)

    monkeypatch.setattr(exp5_world, "_one_library", counted)
    assert run(tmp_path) == 0
    assert calls == [] and (tmp_path / "world_libraries.json").read_text() == first
    (tmp_path / "libraries" / "seed1_0001.json").write_text("{cut")  # a damaged file is acquired again
    assert run(tmp_path) == 0
    assert calls == [(1, 1, "lift")]
    calls.clear()
    assert run(tmp_path, "--table-contact", "grip") == 0  # other settings: every library again
    assert len(calls) == 4 and all(c[2] == "grip" for c in calls)


def test_kept_libraries_serve_the_parallel_path(tmp_path, monkeypatch):
    monkeypatch.setattr(exp5_world, "_one_library", fake_library)
    assert run(tmp_path) == 0
    first = json.loads((tmp_path / "world_libraries.json").read_text())
    # the workers do not see the stand-in: they can only read the kept files
    assert exp5_world.main(["--libraries", "2", "--seed", "0", "1", "--jobs", "2", "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "world_libraries.json").read_text()) == first


def test_a_seed_twice_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(exp5_world, "_one_library", pytest.fail)
    assert exp5_world.main(["--seed", "3", "3", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --seed: each seed once, got 3 3"]



def test_an_interrupt_is_one_line_and_keeps_the_finished_libraries(tmp_path, monkeypatch, capsys):
    def stop_at_the_third(seed, i, table_contact="lift"):
        if (seed, i) == (1, 0):
            raise KeyboardInterrupt
        return fake_library(seed, i, table_contact)

    monkeypatch.setattr(exp5_world, "_one_library", stop_at_the_third)
    assert run(tmp_path) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"interrupted: the finished libraries are kept in {tmp_path / 'libraries'}; the same command resumes"]
    assert sorted(p.name for p in (tmp_path / "libraries").glob("*.json")) == ["seed0_0000.json", "seed0_0001.json"]
    assert not (tmp_path / "world_libraries.json").exists()
