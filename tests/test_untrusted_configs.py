"""Hostile joint maps and experiment configs: bounded YAML (nesting, alias bombs, duplicate keys),
bounded sizes before anything is allocated, and the ``base:`` merging rule
(``retarget_lib.files.read_yaml``, ``retarget_lib.io.rig_maps``, ``retarget_lib.config``,
``retarget_lib.config_schema``)."""

import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from test_untrusted_harness import kato_glb, retarget_argv, run_contained

import retarget_lib.training.run
from retarget_lib.config import load_config
from retarget_lib.config_schema import MAX_TRAINING_BYTES, memory_problem, validate
from retarget_lib.core.skeleton import JointSetError
from retarget_lib.files import REPO_ROOT
from retarget_lib.io.rig_maps import load_mapping_file

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

CONFIGS = REPO_ROOT / "configs"
BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{b}: &{b} [{', '.join(['*' + a] * 10)}]\n"
    for a, b in zip("abcdefgh", "bcdefghi", strict=False)
)


@pytest.fixture(scope="module")
def target(tmp_path_factory):
    return kato_glb(tmp_path_factory.mktemp("kato") / "kato.glb")


def map_run(tmp_path, target, text: str | bytes):
    (tmp_path / "in").mkdir(exist_ok=True)
    joint_map = tmp_path / "in" / "map.yaml"
    joint_map.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "out" / "o.bvh"
    run = run_contained(retarget_argv(target, out, target, "--joint-map", joint_map), tmp_path, out)
    run.assert_contained(joint_map, tmp_path / "in")
    return run, joint_map


# --------------------------------------------------------------------------------- joint maps
@pytest.mark.parametrize(
    "text,problem",
    [
        ("[" * 20_000 + "]" * 20_000, "nested more than 32 deep (the limit)"),
        ("{Head: " * 20_000 + "x" + "}" * 20_000, "nested more than 32 deep (the limit)"),
        (
            "Head: Head\nNeck: Neck\nHead: Spine2\n",
            "line 3 malformed YAML: key 'Head' is given twice (first on line 1)",
        ),
        (BOMB + "Head: *i\n", "holds more than 100000 values once its aliases are expanded"),
        ("Head: Neck\nNeck: Neck\n", "maps both Head and Neck to 'Neck'"),
        ("Head: [a, b]\n", "a joint mapping file holds lines 'CanonicalName: file_joint_name'"),
        ("Head: !!python/object/apply:os.system [touch pwned]\n", "malformed YAML"),
        (b"Head: \xff\xfe\n", "not a UTF-8 text file"),
        ("Hed: Head\n", "names 'Hed', not a canonical joint"),
        ("Head: Nose\n", "maps Head to 'Nose', which is not a joint of the rig"),
        ("Head: Spine\n", "with the joint map"),
    ],
)
def test_a_hostile_joint_map(tmp_path, target, text, problem):
    run, joint_map = map_run(tmp_path, target, text)
    run.assert_error(joint_map, problem)
    assert not (tmp_path / "pwned").exists()


def test_a_joint_map_with_a_key_twice_loses_no_line(tmp_path):
    (tmp_path / "map.yaml").write_text("Head: Head\nHead: Neck\n")
    with pytest.raises(JointSetError, match="key 'Head' is given twice"):
        load_mapping_file(tmp_path / "map.yaml")
    (tmp_path / "map.yaml").write_text("Head: Head\nNeck: Neck\n")
    assert load_mapping_file(tmp_path / "map.yaml") == {"Head": "Head", "Neck": "Neck"}


_YAML_TOKENS = [
    "Head",
    "Neck",
    "Hips",
    "LeftHand",
    "RightFoot",
    ": ",
    "\n",
    "  ",
    "- ",
    "[",
    "]",
    "{",
    "}",
    ", ",
    "&a ",
    "*a",
    "&b ",
    "*b",
    "<<: ",
    "'",
    '"',
    "#",
    "!!str ",
    "!!python/name:os.system ",
    "~",
    "1e400",
    "\t",
    "Spine2",
    "mixamorig:Head",
    "? ",
    "|",
    ">",
    "%YAML 1.1\n",
    "---\n",
    "...\n",
]


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(tokens=st.lists(st.sampled_from(_YAML_TOKENS) | st.text(max_size=4), max_size=40))
def test_fuzz_joint_maps(tmp_path_factory, target, tokens):
    run, _ = map_run(tmp_path_factory.mktemp("map"), target, "".join(tokens))
    assert run.code in (0, 2)


# ------------------------------------------------------------------------------------ configs
def config(tmp_path, text: str):
    path = tmp_path / "in" / "cfg.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text)
    return path


class _Loaded(Exception):
    """Raised by the stand-in for training: the config loaded, nothing was trained."""


@pytest.fixture
def no_training(monkeypatch):
    """``retarget train`` loads and checks the config as usual, then stops before any training."""

    def load_only(config_path, overrides=(), profile=None, *args, **kwargs):
        raise _Loaded(load_config(config_path, overrides, profile))

    monkeypatch.setattr(retarget_lib.training.run, "train_config", load_only)


def train_run(tmp_path, path, *overrides):
    return run_contained(
        ["train", "--config", str(path), *overrides, "--out", str(tmp_path / "run")], tmp_path
    )


@pytest.mark.parametrize(
    "text,overrides,problem",
    [
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\n{BOMB}name: *i\n",
            (),
            "holds more than 100000 values",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\n",
            ("model.channels=200000",),
            "model.channels = 200000 is invalid: must be an integer > 0 and at most 4096",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\n",
            ("train.batch=1000000000",),
            "train.batch = 1000000000 is invalid: must be an integer > 0 and at most 4096",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\n",
            ("model.channels=4096", "train.batch=4096", "data.window=1000"),
            "would need about",
        ),
        (
            f"base: {CONFIGS / 'contact_paper.yaml'}\nmodel: {{hidden: 4096, geometry: 4096}}\n"
            "train: {batch: 4096}\ndata: {window: 1000}\n",
            (),
            "beyond the 64 GiB limit",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\n"
            + "train: "
            + "{a: " * 50
            + "1"
            + "}" * 50
            + "\n",
            (),
            "nested more than 32 deep",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\ntrain: {{steps: 3}}\ntrain: {{batch: 2}}\n",
            (),
            "key 'train' is given twice",
        ),
        (
            f"base: {CONFIGS / 'tdcn_paper.yaml'}\nname: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n",
            (),
            "name = [1, 2, 3, 4, ...]",
        ),
        ("base: [1]\n", (), "base must be the name of a config file"),
        # found by test_fuzz_configs: the indented line continues the base's value, which names no
        # file; the error names the config that refers to it, not the path it could not find
        (f"base: {CONFIGS / 'tdcn_paper.yaml'}\n  model", (), "model' is no config file"),
        (f"base: {CONFIGS / 'tdcn_paper.yaml'}\ntrain: {{lr: {'9' * 400}}}\n", (), "train.lr = "),
        # a choice read late lists its values (losses.contact.EE_SCALES, TABLE3_ROWS)
        (
            f"base: {CONFIGS / 'contact_paper.yaml'}\n",
            ("energy.ee_scale=arms",),
            "must be one of the Eee scales: height, legs",
        ),
        (
            f"base: {CONFIGS / 'contact_paper.yaml'}\n",
            ("energy.row=Efoot",),
            "one of the Table 3 rows: Eskel, Eskel+Efoot, Eskel+Efoot+Eint w/o w,",
        ),
        (
            f"base: {CONFIGS / 'contact_paper.yaml'}\n",
            ("train.decay_from=2",),
            "train.decay_from = 2 is invalid: must be null (no linear tail) or a number in [0, 1]",
        ),
    ],
)
def test_a_hostile_config_stops_before_any_work(tmp_path, no_training, text, overrides, problem):
    path = config(tmp_path, text)
    run = train_run(tmp_path, path, *overrides)
    line = run.assert_error(
        path if not overrides or "would need" in problem else "override", problem
    )
    assert len(line) < 1000
    assert not (tmp_path / "run").exists()


def test_an_override_value_that_is_an_alias_bomb(tmp_path, no_training):
    run = train_run(tmp_path, CONFIGS / "tdcn_paper.yaml", "name=" + BOMB.replace("\n", " ; "))
    run.assert_error("override 'name=")


def test_a_files_own_keys_win_over_its_bases_profile_values(tmp_path):
    path = config(
        tmp_path,
        f"base: {CONFIGS / 'tdcn_paper.yaml'}\nmodel: {{channels: 64}}\ntrain: {{steps: 10}}\n",
    )
    for profile in ("fast", "paper"):
        cfg = load_config(path, profile=profile)
        assert cfg["model"]["channels"] == 64 and cfg["train"]["steps"] == 10, profile
    fast = load_config(path, profile="fast")
    assert (
        fast["model"]["disc_channels"] == 128 and fast["train"]["batch"] == 16
    )  # what the file leaves: the base's


def test_a_files_own_profile_wins_over_its_own_keys(tmp_path):
    path = config(
        tmp_path,
        f"base: {CONFIGS / 'tdcn_paper.yaml'}\nmodel: {{channels: 64}}\n"
        "profiles:\n  fast: {model: {channels: 32}}\n",
    )
    assert load_config(path, profile="fast")["model"]["channels"] == 32
    assert load_config(path, profile="paper")["model"]["channels"] == 64
    assert load_config(path, ["model.channels=16"], profile="fast")["model"]["channels"] == 16


def test_the_training_memory_estimate_separates_the_paper_from_the_absurd():
    paper = load_config(CONFIGS / "tdcn_paper.yaml", profile="paper")
    assert memory_problem(paper) is None
    huge = dict(
        paper,
        model=dict(paper["model"], channels=4096),
        train=dict(paper["train"], batch=4096),
        data=dict(paper["data"], window=1000),
    )
    assert (
        validate(huge) is None
        and "GiB" in memory_problem(huge)
        and MAX_TRAINING_BYTES == 64 * 2**30
    )


_CONFIG_TOKENS = [
    "model",
    "train",
    "data",
    "loss",
    "name",
    "seed",
    "steps",
    "batch",
    "channels",
    "window",
    "profiles",
    "fast",
    "paper",
    "base",
    ": ",
    "\n",
    "  ",
    "{",
    "}",
    "[",
    "]",
    ", ",
    "&a ",
    "*a",
    "-1",
    "0",
    "7",
    "4096",
    "1000000000",
    "1e999",
    "null",
    "true",
    "'x'",
    "tdcn_paper.yaml",
    "../x.yaml",
    "#",
]
_VALUE = st.sampled_from(
    [
        -1,
        0,
        1,
        2,
        16,
        64,
        256,
        4096,
        4097,
        10**9,
        2**70,
        0.5,
        1e-4,
        float("inf"),
        "x",
        None,
        True,
        [1, 2],
        {"a": 1},
    ]
)
_SECTION = st.dictionaries(
    st.sampled_from(
        [
            "channels",
            "disc_channels",
            "hidden",
            "geometry",
            "window",
            "batch",
            "steps",
            "lr",
            "row",
            "dilations",
            "kernel",
            "checkpoint_every",
        ]
    ),
    _VALUE,
    max_size=4,
)
_STRUCTURED = st.fixed_dictionaries(
    {},
    optional={
        "name": _VALUE,
        "seed": _VALUE,
        "model": _SECTION | _VALUE,
        "train": _SECTION,
        "data": _SECTION,
        "profiles": st.dictionaries(
            st.sampled_from(["fast", "paper", "slow"]),
            st.fixed_dictionaries({}, optional={"model": _SECTION, "train": _SECTION}),
            max_size=2,
        ),
    },
).map(yaml.safe_dump)
_TOKENS = st.lists(st.sampled_from(_CONFIG_TOKENS) | st.text(max_size=4), max_size=40).map("".join)


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    text=_STRUCTURED | _TOKENS,
    with_base=st.booleans(),
    overrides=st.lists(
        st.sampled_from(
            [
                "train.steps=5",
                "model.channels=99999",
                "train.batch=2",
                "name=*a",
                "seed=[",
                "train.lr=1e999",
                "model.channels=4096",
                "train.batch=4096",
                "data.window=1000",
            ]
        ),
        max_size=3,
    ),
)
@example(
    text="  model", with_base=True, overrides=[]
)  # a base value that names no file (found by this test)
def test_fuzz_configs(tmp_path_factory, monkeypatch, text, with_base, overrides):
    """A config loads to one that passes the schema and the memory bound, or ``retarget train``
    stops with one line naming the file (or the override) before any work."""
    root = tmp_path_factory.mktemp("cfg")
    path = config(root, (f"base: {CONFIGS / 'tdcn_paper.yaml'}\n" if with_base else "") + text)
    monkeypatch.setattr(
        retarget_lib.training.run,
        "train_config",
        lambda config_path, overrides=(), profile=None, *a, **k: (_ for _ in ()).throw(
            _Loaded(load_config(config_path, overrides, profile))
        ),
    )
    try:
        run = train_run(root, path, *overrides)
    except _Loaded as loaded:
        cfg = loaded.args[0]
        assert validate(cfg) is None and memory_problem(cfg) is None
        return
    line = run.lines[0] if run.lines else ""
    named = next((f"override {o!r}" for o in overrides if f"override {o!r}" in line), path)
    run.assert_contained(named, root / "in")
    assert run.code == 2
