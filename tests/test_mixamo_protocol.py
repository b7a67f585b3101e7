"""The reviewer's path: Table 4 and the contact tables on a ``mixamo-local`` folder
(retarget_lib.evaluation.mixamo, .mixamo_contact), checked on the library's fixture folder and on a
tiny case computed by hand."""

import shutil

import numpy as np
import pandas as pd
import pytest

from retarget_lib.cli import main
from retarget_lib.config import load_config
from retarget_lib.core.character import Character
from retarget_lib.core.skeleton import canonical22_skeleton
from retarget_lib.data.mixamo_splits import (
    folder_split,
    mixamo_contact_training_set,
    mixamo_training_set,
    paper_pairs,
    scenario_of,
    unseen_motions,
)
from retarget_lib.data.sources.mixamo_fixture import write_mixamo_character, write_mixamo_fixture
from retarget_lib.data.sources.mixamo_local import load_mixamo_folder
from retarget_lib.data.status import check_sources
from retarget_lib.data.synthetic.characters import make_character
from retarget_lib.data.synthetic.motions import make_motion
from retarget_lib.errors import MixamoFolderError
from retarget_lib.evaluation.mixamo import CASE_COLUMNS, run_mixamo_tdcn_evaluation
from retarget_lib.evaluation.mixamo_contact import (
    mixamo_contact_cases,
    run_mixamo_contact_evaluation,
)
from retarget_lib.io.fbx import fbx_missing
from retarget_lib.methods.registry import get_method
from retarget_lib.training.contact import ContactTraining
from retarget_lib.training.contact import training_clips as contact_training_clips
from retarget_lib.training.tdcn_data import training_clips


@pytest.fixture(scope="module")
def fixture_root(tmp_path_factory):
    return write_mixamo_fixture(tmp_path_factory.mktemp("mixamo_fixture"))


def test_scenario_rule_gives_the_papers_pairs_their_scenarios():
    """Tables 2-3: pages 18, 23, 28, 33 are performed by scenario 1/2 sources (seen), 45, 51, 52
    only by scenario 3/4 sources (unseen); the rule must put each of the eight pairs in its
    scenario."""
    performers = {
        18: {"Kaya", "Warrok W Kurniawan"},
        28: {"Big Vegas", "Malcolm"},
        23: {"Peasant Man", "Liam"},
        33: {"AJ", "Mutant"},
        51: {"Sporty Granny", "Malcolm"},
        52: {"Claire", "Warrok W Kurniawan", "Mutant"},
        45: {"Mutant", "Liam"},
    }
    unseen = unseen_motions(performers)
    assert unseen == {45, 51, 52}
    pages = {
        ("Kaya", "Warrok W Kurniawan"): 18,
        ("Big Vegas", "Malcolm"): 28,
        ("Peasant Man", "Liam"): 23,
        ("AJ", "Mutant"): 33,
        ("Sporty Granny", "Malcolm"): 51,
        ("Claire", "Warrok W Kurniawan"): 52,
        ("Mutant", "Liam"): 45,
        ("Claire", "Mutant"): 52,
    }
    for (src, tgt), scenario in paper_pairs().items():
        assert scenario_of(tgt, pages[src, tgt], unseen) == scenario


def _scaled(character: Character, s: float, name: str) -> Character:
    """The same character uniformly scaled by ``s``."""
    return Character(
        name,
        canonical22_skeleton(character.skeleton.offsets * s),
        character.rest_vertices * s,
        character.faces,
        character.weights,
    )


def test_copy_row_matches_a_hand_computation(tmp_path):
    """Source A; target B = A scaled by s, whose "own clip" is A's rotations with the root scaled by
    s plus a drift d(t) = c·t/(T−1) along x. ``copy`` keeps the rotations and scales the root by
    the leg ratio (= s), so every joint is off by exactly d(t): nmse = mean_t |d(t)|² / H_B (cm²/cm)
    and the root-relative error is 0. Target C is B exported at 60 fps: the prediction is compared
    at C's frame times k/60, where the drift is c·k/(2(T−1))."""
    T, s, c = 130, 1.25, 0.05
    a = make_character("cleo")
    b = _scaled(a, s, "B")
    clip = make_motion("walk", a.skeleton, 3, duration=5.0).slice(0, T)
    clip.name = "Walk"
    drift = np.zeros((T, 3))
    drift[:, 0] = c * np.arange(T) / (T - 1)
    own = clip.copy(skeleton=b.skeleton, root_positions=clip.root_positions * s + drift)
    write_mixamo_character(tmp_path, a, [clip], name="A")
    write_mixamo_character(tmp_path, b, [own], name="B")
    write_mixamo_character(tmp_path, _scaled(a, s, "C"), [own], name="C", fps=60.0)
    run_mixamo_tdcn_evaluation(
        tmp_path / "out", tmp_path, methods={"copy": get_method("copy").retargeter()}
    )
    rows = pd.read_csv(tmp_path / "out" / "table4_cases.csv").set_index(["source", "target"])
    h_cm = 100.0 * b.skeleton.height()
    t = np.arange(T)
    k = np.arange(2 * T - 1)  # C's frames at 60 fps
    # short: the authors' windows of 130 frames, [0, 120) and the last 120, [10, 130), each
    # retargeted on its own (copy's root is absolute, so the drift is the same) and averaged
    on_b = (c * t / (T - 1)) ** 2
    on_c = (c * k / (2 * (T - 1))) ** 2
    expected = {
        ("A", "B"): (on_b, np.mean([on_b[:120].mean(), on_b[10:130].mean()])),
        ("A", "C"): (on_c, np.mean([on_c[:239].mean(), on_c[20:259].mean()])),
    }
    for pair, (long_sq, short) in expected.items():
        row = rows.loc[pair]
        assert row["frames"] == len(long_sq)
        # BVH text stores 6 decimals (cm, degrees): ~1e-8 m per joint, 1e-5 relative on |d|² at c =
        # 5 cm
        np.testing.assert_allclose(row["nmse"], 1e4 * long_sq.mean() / h_cm, rtol=1e-4)
        np.testing.assert_allclose(row["nmse_short"], 1e4 * short / h_cm, rtol=1e-4)
        assert row["nmse_root_relative"] < 1e-6 and row["nmse_short_root_relative"] < 1e-6


def test_fixture_folder_tables_and_coverage(fixture_root, tmp_path):
    table, coverage, _ = run_mixamo_tdcn_evaluation(
        tmp_path, fixture_root, only=["copy", "copy-rest"]
    )
    for name in ("table4.md", "table4.csv", "table4_cases.csv"):
        assert (tmp_path / name).stat().st_size > 0
    cases = pd.read_csv(tmp_path / "table4_cases.csv")
    assert (
        tuple(cases.columns[:7])
        == CASE_COLUMNS[:7]
        == ("source", "target", "motion", "method", "frames", "nmse", "nmse_root_relative")
    )
    assert set(cases["method"]) == {"copy", "copy-rest"} and np.isfinite(cases["nmse"]).all()
    # Claire is exported at 60 fps: her clips are compared at 60 fps frame times
    into_claire = cases[(cases["target"] == "Claire") & (cases["motion"] == "Sitting Clap")]
    assert (into_claire["truth_fps"] == 60).all() and (into_claire["frames"] == 299).all()
    # the paper's pairs present in the fixture, and the missing ones reported, not an error
    status = coverage.set_index(["source", "target"])["status"]
    assert (
        status["Kaya", "Warrok W Kurniawan"] == "present"
        and status["Claire", "Warrok W Kurniawan"] == "present"
    )
    assert status["AJ", "Mutant"].startswith("missing")
    md = (tmp_path / "table4.md").read_text()
    assert "frame counts differ" in md and "Walking While Texting" in md
    assert set(table.index.get_level_values("pairs")) == {"paper", "all"}


def test_partial_folder_is_a_coverage_report(tmp_path):
    """One character: no pair at all is still a written report."""
    cleo = make_character("cleo")
    write_mixamo_character(
        tmp_path / "in",
        cleo,
        [_named(make_motion("pray", cleo.skeleton, 1).slice(0, 20), "Praying")],
        name="Kaya",
    )
    table, coverage, _ = run_mixamo_tdcn_evaluation(
        tmp_path / "out", tmp_path / "in", methods={"copy": get_method("copy").retargeter()}
    )
    assert table.empty and (coverage["status"] != "present").all()
    assert "(no case)" in (tmp_path / "out" / "table4.md").read_text()


def _named(motion, name):
    motion.name = name
    return motion


def test_cli_evaluate_on_the_folder(fixture_root, tmp_path, capsys):
    assert (
        main(
            [
                "evaluate",
                "--table",
                "tdcn",
                "--data",
                "mixamo-local",
                "--mixamo",
                str(fixture_root),
                "--methods",
                "copy",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "present" in out and "table4_cases.csv" in out
    assert (
        main(
            [
                "evaluate",
                "--table",
                "tdcn",
                "--data",
                "mixamo-local",
                "--mixamo",
                str(tmp_path / "nowhere"),
                "--out",
                str(tmp_path),
            ]
        )
        == 2
    )
    assert "RETARGET_MIXAMO" in capsys.readouterr().err
    assert main(["evaluate", "--table", "tdcn", "--methods", "copy", "--out", str(tmp_path)]) == 2
    assert "--data mixamo-local" in capsys.readouterr().err


def test_contact_coverage_without_the_source_mesh(tmp_path):
    """No Y Bot: every appendix (target, motion) is reported with its reason; no case, no error."""
    cleo = make_character("cleo")
    write_mixamo_character(
        tmp_path / "in",
        cleo,
        [_named(make_motion("pray", cleo.skeleton, 1).slice(0, 20), "Praying")],
        name="Kaya",
    )
    cases, coverage = mixamo_contact_cases(load_mixamo_folder(tmp_path / "in"))
    assert cases == [] and len(coverage) == 30 * 6
    assert set(coverage["status"]) == {"no Y Bot mesh"}
    tables, _, _ = run_mixamo_contact_evaluation(tmp_path / "out", tmp_path / "in", rows=("copy",))
    assert tables["table1"].filter(like="ours").isna().all().all()
    assert (tmp_path / "out" / "contact_coverage.csv").exists() and (
        tmp_path / "out" / "contact_table5.md"
    ).exists()


@pytest.mark.slow
def test_cli_contact_tables_on_the_folder(fixture_root, tmp_path, monkeypatch, capsys):
    """~50 s: contact detection on the source mesh and the geodesic Eint of each target."""
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path / "cache"))
    assert (
        main(
            [
                "evaluate",
                "--table",
                "contact",
                "--data",
                "mixamo-local",
                "--mixamo",
                str(fixture_root),
                "--methods",
                "copy",
                "copy-rest",
                "--out",
                str(tmp_path / "out"),
            ]
        )
        == 0
    )
    assert "contact_coverage.csv" in capsys.readouterr().out
    cases = pd.read_csv(tmp_path / "out" / "contact_cases.csv")
    # Y Bot performs the fixture's three test motions; Kaya lacks "Praying": 5 (motion, target)
    # cases per method
    assert len(cases) == 2 * 5 and set(cases["body"]) == {"skinny", "bulky"}
    table1 = pd.read_csv(tmp_path / "out" / "contact_table1.csv", index_col=0)
    assert np.isfinite(table1.loc["copy", "ours global position MSE"])
    for name in ("contact_table5.md", "contact_table6.md", "contact_coverage.csv"):
        assert (tmp_path / "out" / name).exists()


def test_training_set_follows_the_papers_split(fixture_root):
    """Training characters: the manifest's nine that the folder has (Kaya, Warrok); motions: all but
    the unseen ones ("Praying", performed by the scenario 3/4 source Claire and no 1/2 source)."""
    skeletons, clips = mixamo_training_set(fixture_root)
    assert list(skeletons) == ["Kaya", "Warrok W Kurniawan"]
    assert sorted(ref.name for ref, _ in clips) == [
        "Sitting Clap",
        "Walking",
        "Walking While Texting",
    ]
    assert all(set(own) == set(skeletons) and ref.fps == 30.0 for ref, own in clips)
    # Warrok's "Walking" file has 0.2 % longer rest offsets: it is put on his one training skeleton
    walking = dict((ref.name, own) for ref, own in clips)["Walking"]["Warrok W Kurniawan"]
    # copied, not recomputed: exact
    np.testing.assert_array_equal(walking.skeleton.offsets, skeletons["Warrok W Kurniawan"].offsets)


def test_cli_trains_a_table4_row_on_the_folder(fixture_root, tmp_path, monkeypatch, capsys):
    """A two-step smoke run of TDCN "ours" with data.source=mixamo-local."""
    monkeypatch.setenv("RETARGET_MIXAMO", str(fixture_root))
    out = tmp_path / "run"
    assert (
        main(
            [
                "train",
                "--config",
                "configs/tdcn_paper.yaml",
                "data.source=mixamo-local",
                "train.steps=2",
                "train.batch=2",
                "train.checkpoint_every=2",
                "--profile",
                "fast",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert (out / "final.pt").exists() and len(pd.read_csv(out / "losses.csv")) == 2
    assert (
        main(
            [
                "train",
                "--config",
                "configs/tdcn_paper.yaml",
                "data.source=mixamo",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "data.source" in capsys.readouterr().err


@pytest.mark.data
def test_mixed_training_set_has_both_casts(fixture_root):
    clips = training_clips(False, "mixamo-local+synthetic", str(fixture_root))
    assert {"Kaya", "Warrok W Kurniawan"} < set(clips.characters) and len(clips.characters) > 2
    assert {"Sitting Clap", "Walking While Texting"} < set(
        clips.clip_names
    ) and "Praying" not in clips.clip_names


@pytest.mark.slow
def test_contact_training_runs_on_the_folder(fixture_root, tmp_path, monkeypatch):
    """~30 s (contact detection on each training clip): a two-step run of the Efull row on the
    folder's training characters; the appendix's test motions are never among its sources."""
    monkeypatch.setenv("RETARGET_MIXAMO", str(fixture_root))
    monkeypatch.setenv("RETARGET_CACHE", str(tmp_path / "cache"))
    config = load_config(
        "configs/contact_paper.yaml",
        [
            "data.source=mixamo-local",
            "model.hidden=32",
            "model.geometry=16",
            "train.batch=2",
            "train.steps=2",
        ],
    )
    clips, targets = contact_training_clips(config)
    assert sorted(targets) == ["Kaya", "Warrok W Kurniawan"]
    assert sorted(c.name for c in clips) == ["Kaya/Walking", "Warrok W Kurniawan/Walking"]
    run = ContactTraining(config, clips, targets)
    losses = [run.step(i) for i in range(2)]
    assert all(np.isfinite(v) for log in losses for v in log.values())


# --- splits.yaml: the folder declares its own seen/unseen motions and characters
# ----------------------


def test_splits_yaml_replaces_the_default_rule(fixture_root, tmp_path):
    """With ``unseen_motions: [Walking While Texting]`` and ``seen_characters: [Kaya, Claire]``
    the scenarios, the report and the training set follow the file: "Praying" becomes seen,
    Warrok becomes an unseen (test) character and Claire a training one."""
    root = tmp_path / "folder"
    shutil.copytree(fixture_root, root)
    (root / "splits.yaml").write_text(
        "unseen_motions: [Walking While Texting]\nseen_characters: [Kaya, Claire]\n"
    )
    split = folder_split(load_mixamo_folder(root))
    assert split.unseen_motions == {"Walking While Texting"} and split.train_characters == (
        "Kaya",
        "Claire",
    )
    assert split.motion_rule == split.character_rule == str(root / "splits.yaml")
    run_mixamo_tdcn_evaluation(
        tmp_path / "out", root, methods={"copy": get_method("copy").retargeter()}
    )
    cases = pd.read_csv(tmp_path / "out" / "table4_cases.csv").set_index(
        ["source", "target", "motion"]
    )["scenario"]
    assert cases["Y Bot", "Kaya", "Walking While Texting"] == 3  # unseen motion, seen character
    assert cases["Y Bot", "Warrok W Kurniawan", "Walking While Texting"] == 4
    assert cases["Y Bot", "Claire", "Praying"] == 1  # by default: unseen motion, unseen character
    assert cases["Y Bot", "Warrok W Kurniawan", "Praying"] == 2
    assert "splits.yaml): Walking While Texting" in (tmp_path / "out" / "table4.md").read_text()
    skeletons, clips = mixamo_training_set(root)
    assert list(skeletons) == ["Kaya", "Claire"]
    assert sorted(ref.name for ref, _ in clips) == ["Praying", "Sitting Clap", "Walking"]
    # contact training: the declared seen characters with a mesh, outside the appendix's test
    # motions
    characters, contact_clips = mixamo_contact_training_set(root)
    assert list(characters) == ["Kaya", "Claire"] and [m.name for _, _, m in contact_clips] == [
        "Kaya/Walking"
    ]


def test_splits_yaml_lists_of_the_other_kind(fixture_root, tmp_path):
    """``seen_motions`` makes every other motion unseen; ``unseen_characters`` makes every other
    character of the folder a training character; without the file the default rule holds."""
    root = tmp_path / "folder"
    shutil.copytree(fixture_root, root)
    default = folder_split(load_mixamo_folder(root))
    assert default.unseen_motions == {"Praying"} and default.motion_rule.startswith("default")
    (root / "splits.yaml").write_text(
        "seen_motions: [Walking]\nunseen_characters: [Claire, Y Bot]\n"
    )
    split = folder_split(load_mixamo_folder(root))
    assert split.unseen_motions == {"Praying", "Sitting Clap", "Walking While Texting"}
    assert split.train_characters == ("Kaya", "Warrok W Kurniawan")
    (root / "splits.yaml").write_text("# nothing declared\n")
    assert folder_split(load_mixamo_folder(root)) == default


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "unseen_motions: [Walkin]\n",
            r"unseen_motions names \['Walkin'\], which are not motions \(file stems\)",
        ),
        ("seen_characters: [Kay]\n", r"seen_characters names \['Kay'\], which are not characters"),
        (
            "seen_motions: [Walking]\nunseen_motions: [Praying]\n",
            "give seen_motions or unseen_motions, not both",
        ),
        ("unseen: [Walking]\n", r"unknown keys \['unseen'\]"),
        ("unseen_motions: Walking\n", "unseen_motions must be a list of names"),
        (
            "unseen_motions: [Walking, Walking]\n",
            r"unseen_motions lists \['Walking'\] more than once",
        ),
        ("unseen_motions: [Walking\n", r"not valid YAML \(line 2\)"),
        ("- Walking\n", "must be a mapping"),
    ],
)
def test_an_invalid_splits_yaml_is_refused_before_any_clip_loads(
    tmp_path, capsys, monkeypatch, text, message
):
    """The folder also holds a malformed clip: the splits.yaml error comes first (it is checked
    before any clip is read), names the file, and the command line prints it on one line (exit
    2)."""
    cleo = make_character("cleo")
    write_mixamo_character(
        tmp_path / "in",
        cleo,
        [_named(make_motion("walk", cleo.skeleton, 1).slice(0, 20), "Walking")],
        name="Kaya",
    )
    (tmp_path / "in" / "Kaya" / "Praying.bvh").write_text("HIERARCHY\nnot a bvh\n")
    (tmp_path / "in" / "splits.yaml").write_text(text)
    with pytest.raises(MixamoFolderError, match=message) as e:
        load_mixamo_folder(tmp_path / "in")
    assert str(e.value).startswith(str(tmp_path / "in" / "splits.yaml"))
    assert (
        main(
            [
                "evaluate",
                "--table",
                "tdcn",
                "--data",
                "mixamo-local",
                "--mixamo",
                str(tmp_path / "in"),
                "--methods",
                "copy",
                "--out",
                str(tmp_path / "out"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "splits.yaml" in err
    monkeypatch.setenv("RETARGET_MIXAMO", str(tmp_path / "in"))
    status = {s.id: s for s in check_sources()}["mixamo-local"]
    assert status.state == "BAD" and "splits.yaml" in status.detail


@pytest.mark.slow
@pytest.mark.parametrize("clip_format, mesh", [("glb", "glb"), ("fbx", "fbx")])
def test_the_glb_and_fbx_fixtures_give_the_bvh_fixtures_table(
    fixture_root, tmp_path, clip_format, mesh
):
    """~25 s (GLB) / ~60 s (FBX, converted by assimp) writing and reading 13 clips: the fixture
    written as a GLB download (clips without a skin, a T-pose ``<Character>.glb`` per character) or
    an FBX download (skinned FBX clips in centimetres, a T-pose ``<Character>.fbx``) gives the same
    ``copy`` cases as the BVH + shape.npz fixture."""
    if clip_format == "fbx" and fbx_missing():
        pytest.skip(f"fbx extra not installed: {fbx_missing()}")
    root = write_mixamo_fixture(tmp_path / clip_format, clip_format=clip_format, mesh=mesh)
    assert not list(root.glob("*/*.bvh")) and not list(root.glob("*/shape.npz"))
    methods = {"copy": get_method("copy").retargeter()}
    run_mixamo_tdcn_evaluation(tmp_path / "out_new", root, methods=methods)
    run_mixamo_tdcn_evaluation(tmp_path / "out_bvh", fixture_root, methods=methods)
    key = ["source", "target", "motion"]
    new = pd.read_csv(tmp_path / "out_new" / "table4_cases.csv").set_index(key).sort_index()
    bvh = pd.read_csv(tmp_path / "out_bvh" / "table4_cases.csv").set_index(key).sort_index()
    assert new.index.equals(bvh.index) and (new["scenario"] == bvh["scenario"]).all()
    assert (new["frames"] == bvh["frames"]).all() and (new["truth_fps"] == bvh["truth_fps"]).all()
    # float32 (GLB metres, FBX centimetres) vs 6 decimals of cm (BVH): positions agree to ~1e-6 m,
    # nMSE to ~1e-4 cm²/cm
    np.testing.assert_allclose(new["nmse"], bvh["nmse"], rtol=1e-3, atol=1e-4)
    # assimp may reorder an FBX's vertices: compare them sorted
    got = np.sort(load_mixamo_folder(root).character("Y Bot").rest_vertices, axis=0)
    np.testing.assert_allclose(
        got,
        np.sort(load_mixamo_folder(fixture_root).character("Y Bot").rest_vertices, axis=0),
        atol=1e-5,
    )
