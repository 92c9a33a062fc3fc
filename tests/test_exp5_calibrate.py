"""The Exp 5 world's calibration search (``experiments.exp5.calibrate``, docs/world_calibration.md):
a tiny search in a journal, resumed from it, an interrupted trial retried, and bad input."""
from __future__ import annotations

import pytest

optuna = pytest.importorskip("optuna")

from neuroimagery.experiments.exp5 import calibrate as cal  # noqa: E402
from neuroimagery.robot.world_candidate import PRESENT  # noqa: E402

TINY = ["--babble", "20", "--libraries", "1", "--fk-movements", "60"]


def _trials(path):
    study = cal.open_study(path, dict(babble=20, libraries=1, fk_movements=60), 0)
    return study, study.get_trials(deepcopy=False)


@pytest.fixture(scope="module")
def present_screened(tmp_path_factory):
    """A journal (``j.journal`` and its work folder) whose one trial is the present world screened
    at the tiny sizes, stage 1's pull-path threshold lifted so that it reaches the screen. Made once
    for the tests of this file that start from it (each works on a copy): the present world's
    screen is the search's costliest trial."""
    d = tmp_path_factory.mktemp("present")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cal, "BEHIND_MAX", 1.0)
        assert cal.main(["--storage", str(d / "j.journal"), "--trials", "1", *TINY]) == 0
    return d


def _copy(present_screened, tmp_path):
    import shutil

    shutil.copytree(present_screened, tmp_path, dirs_exist_ok=True)
    return tmp_path / "j.journal"


def test_a_tiny_search_screens_the_present_world_first_and_resumes_from_its_journal(present_screened, tmp_path,
                                                                                     monkeypatch, capsys):
    """At tiny sizes the first trial is the present world re-expressed (stage 1's pull-path
    threshold lifted so that it reaches the screen), measured with the acceptance code; a rerun
    adds two trials to the same journal and keeps the first. (The first call, one trial, is the
    file's shared journal.)"""
    monkeypatch.setattr(cal, "BEHIND_MAX", 1.0)
    journal = _copy(present_screened, tmp_path)
    study, trials = _trials(journal)
    assert len(trials) == 1
    first = trials[0]
    assert {k: first.params[k] for k in PRESENT if k in first.params} == {k: v for k, v in PRESENT.items() if k in first.params}
    assert first.user_attrs["stage"] == "screened"
    m = first.user_attrs["measures"]
    assert 0 <= m["w1"] <= 24 and 0 <= m["w2"] <= 24 and m["libraries"] == 1 and m["movements_per_posture"] == 20
    assert first.values == [m["w3"], m["w4"], m["w1"] + m["w2"]]
    assert first.user_attrs["pulls"]["movements"] == 60
    assert [d["moved"] for d in first.user_attrs["placed"]] == [False] * 4  # the present world is reachable
    kept = sorted(p.name for p in (tmp_path / "j.journal.d").rglob("*.json"))
    assert "posture1_seed100.json" in kept and "seed100_0000.json" in kept

    assert cal.main(["--storage", str(journal), "--trials", "2", *TINY]) == 0
    assert "3 candidates" in capsys.readouterr().out
    _, again = _trials(journal)
    assert len(again) == 3
    assert again[0].values == first.values and again[0].params == first.params


def test_an_interrupted_trial_is_kept_as_failed_and_retried_with_its_parameters(tmp_path, monkeypatch, capsys):
    from neuroimagery.robot.config import WorldConfig

    monkeypatch.setattr(cal, "stage1", lambda p, folder, n: (WorldConfig(), [], None, []))

    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cal, "measure", stop)
    journal = tmp_path / "j.journal"
    assert cal.main(["--storage", str(journal), "--trials", "3", *TINY]) == 130
    assert "interrupted:" in capsys.readouterr().err
    _, trials = _trials(journal)
    assert [t.state for t in trials] == [optuna.trial.TrialState.FAIL]

    fake = dict(w1=20, w2=20, w3=0.0, w4=1.0, pull_alone=0, with_pull=1, routes=1, libraries=1)
    monkeypatch.setattr(cal, "measure", lambda *a, **k: fake)
    assert cal.main(["--storage", str(journal), "--trials", "1", *TINY]) == 0
    _, trials = _trials(journal)
    assert len(trials) == 2 and trials[1].params == trials[0].params
    assert trials[1].values == [0.0, 1.0, 40.0]


@pytest.mark.parametrize("argv, says", [
    (["--trials", "0"], "--trials must be >= 1"),
    (["--stage", "tune"], "invalid choice"),
    (["--babble", "1.5"], "not a whole number"),
    (["--confirm-seeds", "0", "5"], "--confirm-seeds"),
])
def test_bad_input_is_one_error_line_before_any_work(tmp_path, capsys, argv, says):
    assert cal.main(["--storage", str(tmp_path / "j.journal"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and says in err[0]
    assert not (tmp_path / "j.journal").exists()


def test_a_journal_of_other_sizes_a_missing_folder_or_a_foreign_file_is_refused(tmp_path, capsys):
    journal = tmp_path / "j.journal"
    cal.open_study(journal, dict(babble=20, libraries=1, fk_movements=60), 0)
    assert cal.main(["--storage", str(journal), "--stage", "report", "--babble", "30", "--libraries", "1",
                     "--fk-movements", "60"]) == 2
    assert "was screened with" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    assert cal.main(["--storage", str(tmp_path / "file" / "j.journal"), "--stage", "screen"]) == 2
    assert "cannot make its folder" in capsys.readouterr().err
    assert cal.main(["--storage", str(tmp_path / "none.journal"), "--stage", "report"]) == 2
    assert "no such journal" in capsys.readouterr().err
    foreign = tmp_path / "notes.txt"
    foreign.write_text("not a journal\n")
    assert cal.main(["--storage", str(foreign), "--stage", "report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")


def test_a_journal_searched_before_the_reachability_table_is_only_reported(tmp_path, capsys):
    journal = tmp_path / "old.journal"
    study = cal.open_study(journal, dict(babble=20, libraries=1, fk_movements=60), 0)
    study.set_user_attr("sampling", None)  # as a journal of the first form has no such mark
    assert cal.main(["--storage", str(journal), "--stage", "screen", *TINY]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "new journal" in err[0]
    assert cal.main(["--storage", str(journal), "--stage", "report", *TINY]) == 0


def test_a_resized_journal_screens_its_former_screens_again_and_compares_only_one_size(tmp_path, monkeypatch, capsys):
    """The fourth amendment: a journal screened at one size is refused at another unless
    ``--resize``; then its screen of the former size is screened again at the new one with the
    same parameters, and the front and the rule see only the new size's screens."""
    from neuroimagery.robot.config import WorldConfig

    monkeypatch.setattr(cal, "stage1", lambda p, folder, n: (WorldConfig(), [], None, []))
    seen = []

    def fake(cfg, sigma, folder, babble, bseeds, libraries, lseeds):
        seen.append((folder.name, babble, libraries))
        return dict(w1=20 + babble % 3, w2=20, w3=0.0, w4=1.0, pull_alone=0, with_pull=1, routes=1,
                    libraries=libraries)

    monkeypatch.setattr(cal, "measure", fake)
    journal = tmp_path / "j.journal"
    assert cal.main(["--storage", str(journal), "--trials", "1", *TINY]) == 0
    small = ["--babble", "10", "--libraries", "2", "--fk-movements", "60"]
    assert cal.main(["--storage", str(journal), "--trials", "1", *small]) == 2
    assert "--resize" in capsys.readouterr().err
    assert cal.main(["--storage", str(journal), "--trials", "2", "--resize", *small]) == 0
    study = cal.open_study(journal, dict(babble=10, libraries=2, fk_movements=60), 0)
    trials = study.get_trials(deepcopy=False)
    assert len(trials) == 3 and trials[1].params == trials[0].params and trials[2].params != trials[0].params
    assert seen[0][1:] == (20, 1) and seen[1] == (seen[0][0], 10, 2) and seen[2][1:] == (10, 2)
    assert study.user_attrs["sizes_history"] == [dict(sizes=dict(babble=20, libraries=1, fk_movements=60),
                                                      before_trial=1)]
    assert [t.number for t in cal.screened_at(study, dict(babble=10, libraries=2, fk_movements=60))] == [1, 2]
    assert cal.screen_sizes(study, trials[0])["babble"] == 20
    assert cal.main(["--storage", str(journal), "--trials", "1", *small]) == 0  # enqueued once only
    assert len(cal.open_study(journal, dict(babble=10, libraries=2, fk_movements=60), 0).get_trials()) == 4
    capsys.readouterr()
    assert cal.main(["--storage", str(journal), "--stage", "report", *small]) == 0
    out = capsys.readouterr().out
    front, former = out.split("Screened at former sizes")
    assert "| trial 0 " not in front and "| trial 0 (" in former and "| trial 1 |" in front


def test_confirm_measures_the_first_by_the_rule_at_the_confirmation_size_not_the_screens(present_screened, tmp_path,
                                                                                         monkeypatch):
    """The fifth amendment: candidates ranked among the journal's screens (here the present
    world's, the file's shared journal), measured at ``--confirm-size`` per seed on the
    calibration seeds."""
    journal = _copy(present_screened, tmp_path)
    calls = []

    def fake(cfg, sigma, folder, babble_n, babble_seeds, libraries_n, library_seeds):
        calls.append((babble_n, babble_seeds, libraries_n, library_seeds))
        return dict(w1=1, w2=2, w3=1.0, w4=0.0, pull_alone=1, with_pull=1, routes=0, libraries=libraries_n * 2)

    monkeypatch.setattr(cal, "measure", fake)
    assert cal.main(["--storage", str(journal), "--stage", "confirm", "--confirm", "1", "--confirm-seeds", "3", "2",
                     "--confirm-size", "40", "3", *TINY]) == 0
    assert calls == [(40, [100, 101, 102], 3, [100, 101])]
    study, trials = _trials(journal)
    assert study.user_attrs[f"confirmed_{trials[0].number}"]["libraries"] == 6
