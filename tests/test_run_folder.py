"""One folder, one run (harness/runner/folder.py): a run's files are put in place whole, with a manifest
naming the run; another run's folder is refused (exit 2, untouched) unless --replace; files no run wrote
are never replaced; two commands writing one folder at once leave one of them whole."""

from __future__ import annotations

import json
import multiprocessing
from pathlib import Path

import pytest

from harness.base.tomlio import InputError
from harness.cli import main
from harness.runner.folder import MANIFEST_FILE, Manifest, claim, new_id, place, sha256, verify
from tests.conftest import SCENARIOS


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _writers(texts: dict[str, str]) -> dict:
    return {name: (lambda p, text=text: p.write_text(text)) for name, text in texts.items()}


def test_a_placed_run_lists_every_file_with_its_digest_and_each_subfolder_has_a_manifest_of_its_own(tmp_path):
    run = new_id()
    place(tmp_path / "out", _writers({"results.json": "{}", "identified/robot.toml": "a", "identified/x.urdf": "b"}),
          "run", "s", run)
    root, sub = verify(tmp_path / "out"), verify(tmp_path / "out" / "identified")
    assert root.run == sub.run == run and (root.kind, root.name) == ("run", "s")
    assert set(root.files) == {"results.json", "identified/robot.toml", "identified/x.urdf",
                               f"identified/{MANIFEST_FILE}"}
    assert set(sub.files) == {"robot.toml", "x.urdf"}
    assert sub.files["x.urdf"] == sha256(tmp_path / "out" / "identified" / "x.urdf")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging folder left beside it


def test_a_run_of_the_same_scenario_replaces_the_earlier_one_whole(tmp_path):
    out = tmp_path / "out"
    place(out, _writers({"results.json": "1", "identified/drives.toml": "d", "identified/robot.toml": "1"}),
          "run", "s", new_id())
    place(out, _writers({"results.json": "2", "identified/robot.toml": "2"}), "run", "s", new_id())
    assert _snapshot(out).keys() == {"results.json", MANIFEST_FILE, "identified/robot.toml",
                                     f"identified/{MANIFEST_FILE}"}  # the earlier drives.toml is gone
    assert (out / "results.json").read_text() == "2"


def test_another_scenarios_folder_is_refused_untouched_unless_replace_is_given(tmp_path):
    out = tmp_path / "out"
    place(out, _writers({"results.json": "tx40", "identified/drives.toml": "d"}), "run", "tx40", new_id())
    before = _snapshot(out)
    with pytest.raises(InputError, match=r"holds a run of 'tx40': give another folder, or --replace"):
        place(out, _writers({"results.json": "p"}), "run", "parallelogram", new_id())
    assert _snapshot(out) == before
    place(out, _writers({"results.json": "p"}), "run", "parallelogram", new_id(), replace=True)
    assert set(_snapshot(out)) == {"results.json", MANIFEST_FILE}


def test_a_folder_holding_files_no_run_wrote_is_never_replaced(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    for replace in (False, True):
        with pytest.raises(InputError, match=r"holds files no harness run wrote \(notes.txt\)"):
            claim(out, "run", "s", replace)
    place(tmp_path / "run", _writers({"results.json": "1"}), "run", "s", new_id())
    (tmp_path / "run" / "mine.csv").write_text("x")  # beside a run: the folder is no longer the run's alone
    with pytest.raises(InputError, match=r"mine.csv"):
        place(tmp_path / "run", _writers({"results.json": "2"}), "run", "s", new_id(), replace=True)
    assert (tmp_path / "run" / "results.json").read_text() == "1"


def test_verify_refuses_a_file_changed_added_or_missing_since_the_run(tmp_path):
    out = tmp_path / "out"
    run = new_id()
    place(out, _writers({"a.toml": "a", "b.toml": "b"}), "run", "s", run)
    (out / "a.toml").write_text("edited")
    with pytest.raises(InputError, match=rf"a.toml: changed since run {run}"):
        verify(out)
    (out / "a.toml").write_text("a")
    (out / "c.toml").write_text("c")
    with pytest.raises(InputError, match=rf"c.toml: not written by run {run}"):
        verify(out)
    (out / "c.toml").unlink()
    (out / "b.toml").unlink()
    with pytest.raises(InputError, match=r"b.toml: missing"):
        verify(out)
    (out / MANIFEST_FILE).unlink()
    with pytest.raises(InputError, match=r"manifest.json: missing: not a folder a harness run wrote whole"):
        verify(out)


def _place_in_turn(out: str, name: str, files: list[str], rounds: int, replace: bool) -> list[str]:
    """A process placing its run `rounds` times; what it was refused, each time."""
    refused = []
    for _ in range(rounds):
        try:
            place(Path(out), _writers({f: name for f in files}), "run", name, new_id(), replace=replace)
        except InputError as exc:
            refused.append(exc.message)
    return refused


@pytest.mark.parametrize("replace", [False, True])
def test_two_commands_writing_one_folder_at_once_leave_one_run_whole(tmp_path, replace):
    """Two processes placing runs of two scenarios into one folder, 20 times each at once: after each
    round the folder is one run's files, whole (its manifest verifies, every file holds that run's
    text); without --replace the later one is refused and the earlier stands."""
    out = tmp_path / "out"
    jobs = [("a", ["results.json", "report.html", "identified/robot.toml", "identified/drives.toml"]),
            ("b", ["results.json", "data.csv", "identified/robot.xml"])]
    with multiprocessing.get_context("fork").Pool(2) as pool:
        refused = pool.starmap(_place_in_turn, [(str(out), name, files, 20, replace) for name, files in jobs])
    manifest = verify(out)
    verify(out / "identified")
    assert {(out / f).read_text() for f in manifest.files if not f.endswith(MANIFEST_FILE)} == {manifest.name}
    assert set(manifest.files) - {f"identified/{MANIFEST_FILE}"} == set(dict(jobs)[manifest.name])
    if replace:
        assert refused == [[], []]
    else:  # the first to place holds the folder; every placement of the other is refused
        assert sorted(len(r) for r in refused) == [0, 20]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def _cli(*args) -> int:
    return main(["run", *map(str, args), "--quiet"])


def test_harness_run_refuses_another_scenarios_folder_and_replaces_its_own(tmp_path, capsys):
    """`harness run A --out F` then `harness run B --out F`: exit 2 in one line, F byte for byte as A left
    it; with --replace, B's files alone; A again into A's folder: A's, whole."""
    out = tmp_path / "out"
    assert _cli(SCENARIOS / "kr500_rail.toml", "--out", out) == 0
    before = _snapshot(out)
    capsys.readouterr()
    assert _cli(SCENARIOS / "kr500_rail_7digits.toml", "--out", out) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"harness: error: {out}: --out: holds a run of 'kr500_rail': give another folder, or --replace to "
                   "replace it with this run of 'kr500_rail_7digits'")
    assert _snapshot(out) == before
    assert _cli(SCENARIOS / "kr500_rail_7digits.toml", "--out", out, "--replace") == 0
    manifest = verify(out)
    assert manifest.name == "kr500_rail_7digits"
    assert json.loads((out / "results.json").read_text())["run"]["id"] == manifest.run
    assert _cli(SCENARIOS / "kr500_rail_7digits.toml", "--out", out) == 0
    assert verify(out).run != manifest.run


def test_several_scenarios_go_into_folders_of_their_own_never_into_a_runs_folder(tmp_path, capsys):
    out = tmp_path / "out"
    assert _cli(SCENARIOS / "kr500_rail.toml", "--out", out) == 0
    capsys.readouterr()
    assert _cli(SCENARIOS / "kr500_rail.toml", SCENARIOS / "kr500_rail_7digits.toml", "--out", out) == 2
    assert "holds a run of 'kr500_rail': with several scenarios, --out is the folder that gets one folder per " \
           "scenario" in capsys.readouterr().err


def test_harness_report_rewrites_the_runs_report_and_its_manifest(fast_run, tmp_path):
    import shutil

    folder = tmp_path / "run"
    shutil.copytree(fast_run, folder)
    (folder / "report.html").write_text("stale")
    assert main(["report", str(folder / "results.json")]) == 0
    manifest = verify(folder)
    assert manifest == Manifest.read(folder)
    assert (folder / "report.html").read_bytes() == (fast_run / "report.html").read_bytes()


def test_a_folder_a_run_wrote_before_manifests_is_refused_with_the_reason(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("results.json", "report.html", "recording.csv"):
        (out / name).write_text("{}")
    with pytest.raises(InputError, match=r"holds a run written before runs carried a manifest \(its results.json\): "
                                         r"remove it"):
        claim(out, "run", "s", True)
