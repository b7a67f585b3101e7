"""The exercise checks (retarget_lib/notebook/exercises.py) on hand-made answers: a right answer
passes, each classic mistake fails with a one-line message that names the exercise, says why and
shows no number of the reference; an unanswered exercise prints one line and does not raise;
constant guesses never pass, and an exercise a guess could pass is refused when it is written."""

import re

import numpy as np
import pytest
import torch

from retarget_lib.core import rotations as R
from retarget_lib.core.kinematics import forward_kinematics
from retarget_lib.notebook.exercises import (
    GUESSES,
    Case,
    ExerciseAuthoringError,
    ExerciseError,
    NotAnswered,
    assert_not_guessable,
    check_function,
    check_prediction,
    check_value,
    lab_animation,
    random_pose,
)

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def no_number_but_the_label(message: str, label: str) -> None:
    """The message names the exercise and contains no other digit (no value, shape or size)."""
    assert message.startswith(f"Exercise {label}: "), message
    assert "\n" not in message
    assert not re.search(r"\d", message.replace(f"Exercise {label}", "")), message


def fails(label: str, call, *why: str) -> str:
    with pytest.raises(ExerciseError) as info:
        call()
    message = str(info.value)
    no_number_but_the_label(message, label)
    for part in why:
        assert part in message, message
    assert info.value._render_traceback_() == [message]  # Jupyter shows the line, no traceback
    return message


# ------------------------------------------------------------------------------ function exercises
def fk(rotations, offsets, parents, root):
    return forward_kinematics(rotations, offsets, parents, root).positions


def fk_cases():
    return [
        Case(random_pose(0, 5, 6), name="a random tree"),
        Case(lambda: random_pose(1, 1, 3), name="a single frame"),
        Case(random_pose(2, 3, 9, identity=True), name="identity rotations", hint="IDENTITY"),
        Case(random_pose(3, 4, 12, max_degrees=30), name="small turns"),
    ]


def fk_by_matrices(rotations, offsets, parents, root, transpose=False, scale=1.0, xyzw=False):
    if xyzw:
        rotations = rotations[..., [3, 0, 1, 2]]
    local = R.quat_to_matrix(rotations)
    if transpose:
        local = local.transpose(-1, -2)
    G, x = [local[:, 0]], [root * scale]
    for j in range(1, len(parents)):
        p = parents[j]
        x.append(x[p] + G[p] @ (offsets[j] * scale))
        G.append(G[p] @ local[:, j])
    return torch.stack(x, 1)


def test_a_right_function_passes(capsys):
    check_function("01.2", fk_by_matrices, fk, fk_cases())
    assert capsys.readouterr().out == "Exercise 01.2: correct\n"


def test_wrong_functions_fail_naming_the_exercise_and_why():
    cases = fk_cases()

    def transposed(*a):
        return fk_by_matrices(*a, transpose=True)

    def centimetres(*a):
        return fk_by_matrices(*a, scale=100.0)

    def xyzw_input(*a):
        return fk_by_matrices(*a, xyzw=True)

    def zeros(rotations, offsets, parents, root):
        return torch.zeros(*rotations.shape[:-1], 3, dtype=torch.float64)

    def constant(*a):
        return 0.0

    def quaternions_not_positions(rotations, offsets, parents, root):
        return rotations

    # mistakes in reading the input quaternions, named when the check knows which arguments are
    # quaternions; else the identity input's hint says it
    q = {"quaternion_args": (0,)}
    fails(
        "01.2",
        lambda: check_function("01.2", transposed, fk, cases, **q),
        "transposed",
        "column vectors",
    )
    fails("01.2", lambda: check_function("01.2", xyzw_input, fk, cases, **q), "(x, y, z, w)")
    fails("01.2", lambda: check_function("01.2", xyzw_input, fk, cases), "IDENTITY")
    fails("01.2", lambda: check_function("01.2", centimetres, fk, cases, **q), "centimetres")
    fails("01.2", lambda: check_function("01.2", zeros, fk, cases), "all zeros")
    fails("01.2", lambda: check_function("01.2", constant, fk, cases), "same result whatever")
    fails(
        "01.2",
        lambda: check_function("01.2", quaternions_not_positions, fk, cases),
        "wrong shape",
        "last axis",
    )


def test_an_exception_of_the_student_function_is_one_line_with_its_type_and_hint():
    def broken(rotations, offsets, parents, root):
        return rotations[:, 99]

    def no_return(*a):
        fk(*a)

    m = fails(
        "01.2",
        lambda: check_function("01.2", broken, fk, fk_cases(), hint="walk the tree"),
        "IndexError",
        "Hint: walk the tree",
    )
    assert "Traceback" not in m
    fails("01.2", lambda: check_function("01.2", no_return, fk, fk_cases()), "None")


def test_quaternion_results_are_compared_sign_free_and_their_mistakes_named(capsys):
    def turn(q, axis_angle):
        return R.quat_mul(q, R.quat_from_axis_angle(axis_angle))

    qs = [R.quat_normalize(torch.randn(n, 4, dtype=torch.float64)) for n in (1, 3, 5, 7)]
    cases = [(q, torch.full((len(q), 3), 0.3, dtype=torch.float64)) for q in qs]
    check_function("03.1", lambda q, a: -turn(q, a), turn, cases, compare="quaternion")
    assert capsys.readouterr().out == "Exercise 03.1: correct\n"
    with pytest.raises(ExerciseError):  # without compare="quaternion", -q is another array
        check_function("03.1", lambda q, a: -turn(q, a), turn, cases)
    fails(
        "03.1",
        lambda: check_function(
            "03.1", lambda q, a: turn(q, a)[..., [1, 2, 3, 0]], turn, cases, compare="quaternion"
        ),
        "(x, y, z, w)",
    )
    fails(
        "03.1",
        lambda: check_function(
            "03.1", lambda q, a: R.quat_conjugate(turn(q, a)), turn, cases, compare="quaternion"
        ),
        "inverse",
    )
    fails(
        "03.1",
        lambda: check_function(
            "03.1", lambda q, a: 2 * turn(q, a), turn, cases, compare="quaternion"
        ),
        "unit length",
    )


def test_a_transposed_matrix_and_degrees_are_recognised():
    angles = [torch.tensor(a, dtype=torch.float64) for a in ([0.2, 0.5, -1.0], [1.2, 0, 0.1])]
    angles += [torch.randn(4, 3, dtype=torch.float64), torch.randn(2, 3, dtype=torch.float64)]
    cases = [(R.quat_from_axis_angle(a),) for a in angles]
    fails(
        "01.7",
        lambda: check_function(
            "01.7", lambda q: R.quat_to_matrix(q).transpose(-1, -2), R.quat_to_matrix, cases
        ),
        "transposed",
        "column vectors",
    )
    fails(
        "01.8",
        lambda: check_function(
            "01.8",
            lambda q: torch.rad2deg(R.quat_angle(q)),
            R.quat_angle,
            cases,
        ),
        "degrees",
    )


def test_a_forbidden_library_call_fails():
    def lazy(*a):
        return forward_kinematics(*a).positions

    fails(
        "01.2",
        lambda: check_function("01.2", lazy, fk, fk_cases(), forbid=["forward_kinematics"]),
        "without forward_kinematics",
    )


def test_a_function_not_answered_prints_one_line_and_does_not_raise(capsys):
    def fk_lab(rotations, offsets, parents, root):
        raise NotImplementedError

    check_function("01.2", fk_lab, fk, fk_cases())
    check_function("01.2", NotAnswered, fk, fk_cases())
    assert capsys.readouterr().out == "Exercise 01.2: not answered yet\n" * 2


def test_function_exercises_a_guess_could_pass_are_refused_when_written():
    cases = [((k,),) for k in range(4)]
    with pytest.raises(ExerciseAuthoringError, match="cases"):
        check_function("01.2", NotAnswered, fk, fk_cases()[:3])
    with pytest.raises(ExerciseAuthoringError, match="returning 0"):
        check_function("02.1", NotAnswered, lambda x: 0.0 * sum(x), cases)
    with pytest.raises(ExerciseAuthoringError, match="filled with 0"):
        check_function("02.1", NotAnswered, lambda x: 0.0 * np.asarray(x), cases)
    with pytest.raises(ExerciseAuthoringError, match="same answer"):
        check_function("02.1", NotAnswered, lambda x: np.array([2.0, 3.0]), cases)
    with pytest.raises(ExerciseAuthoringError, match="reference raised"):
        check_function("02.1", NotAnswered, lambda x: x[9], cases)
    with pytest.raises(ExerciseAuthoringError, match="label"):
        check_function("1.2", NotAnswered, fk, fk_cases())


def test_a_custom_comparator_says_why():
    def same_norm(student, reference, args):
        if abs(np.linalg.norm(student) - np.linalg.norm(reference)) < 1e-9:
            return None
        return "the length is not kept"

    cases = [(np.array(v, dtype=float),) for v in ([1, 2, 3], [0, 4, 0], [2, 2, 1], [5, 0, 0])]
    check_function("02.2", lambda v: -v, lambda v: v, cases, compare=same_norm)
    fails(
        "02.2",
        lambda: check_function("02.2", lambda v: 2 * v, lambda v: v, cases, compare=same_norm),
        "the length is not kept",
    )


# ---------------------------------------------------------------------------------- value exercises
def test_check_value_right_wrong_and_not_answered(capsys):
    wrist = np.array([0.3, 0.25, 0.0])
    check_value("01.1", wrist + 1e-9, wrist)
    check_value("01.1", NotAnswered, wrist)
    assert capsys.readouterr().out == "Exercise 01.1: correct\nExercise 01.1: not answered yet\n"
    fails("01.1", lambda: check_value("01.1", wrist * 100, wrist), "centimetres")
    fails("01.1", lambda: check_value("01.1", -wrist, wrist), "sign")
    fails("01.1", lambda: check_value("01.1", wrist[:2], wrist), "wrong shape")
    fails("01.1", lambda: check_value("01.1", "0.3", wrist), "string")
    m = fails("01.1", lambda: check_value("01.1", wrist + 0.2, wrist, hint="bend the elbow"))
    assert "0.3" not in m and "Hint: bend the elbow" in m


@pytest.mark.parametrize("guess", list(GUESSES) + [np.zeros(3), [1.0, 1.0, 1.0], np.array([])])
def test_check_value_refuses_constant_guesses(guess):
    fails("01.5", lambda: check_value("01.5", guess, np.array([0.3, 0.25, 0.0])), "guess")
    fails("01.5", lambda: check_value("01.5", guess, 1.37), "guess")


@pytest.mark.parametrize("reference", list(GUESSES) + [np.zeros(3), np.ones((2, 2)), 1.0 + 1e-9])
def test_an_exercise_whose_answer_is_a_guess_is_refused_when_written(reference):
    with pytest.raises(ExerciseAuthoringError, match="01.9"):
        assert_not_guessable(reference, label="01.9")
    with pytest.raises(ExerciseAuthoringError):  # even before the student answers
        check_value("01.9", NotAnswered, reference)


def test_quaternion_values_sign_free():
    q = R.quat_normalize(torch.tensor([0.9, 0.1, -0.3, 0.2], dtype=torch.float64))
    check_value("01.6", -q, q, compare="quaternion")
    fails("01.6", lambda: check_value("01.6", q[[1, 2, 3, 0]], q, compare="quaternion"), "(x, y,")


# ------------------------------------------------------------------------------------- predictions
def test_direction_predictions(capsys):
    check_prediction("01.3", "up", 0.02)
    check_prediction("01.3", " Down ", -0.5)
    check_prediction("01.3", "same", 1e-12)
    check_prediction("01.3", NotAnswered, 0.02)
    assert capsys.readouterr().out.splitlines() == [
        "Exercise 01.3: correct",
        "Exercise 01.3: correct",
        "Exercise 01.3: correct",
        "Exercise 01.3: not answered yet",
    ]
    fails("01.3", lambda: check_prediction("01.3", "down", 0.02), "it went up, not 'down'")
    fails("01.3", lambda: check_prediction("01.3", "up", 0.0), "did not change")
    fails("01.3", lambda: check_prediction("01.3", "higher", 0.02), "'up', 'down' or 'same'")
    for guess in (0, True, None):
        fails("01.3", lambda g=guess: check_prediction("01.3", g, 0.02))


def test_order_of_magnitude_predictions(capsys):
    check_prediction("01.4", -2, 0.0063, kind="order")  # nearest power of ten on a log scale
    check_prediction("01.4", -3.0, 0.0029, kind="order")
    check_prediction("01.4", 1, 12.0, kind="order")
    assert capsys.readouterr().out.count("correct") == 3
    fails("01.4", lambda: check_prediction("01.4", -1, 0.0063, kind="order"), "smaller")
    fails("01.4", lambda: check_prediction("01.4", -4, 0.0063, kind="order"), "larger")
    fails("01.4", lambda: check_prediction("01.4", 0.01, 0.0063, kind="order"), "not the value")
    fails("01.4", lambda: check_prediction("01.4", "-2", 0.0063, kind="order"), "integer")
    for guess in GUESSES:
        with pytest.raises(ExerciseError):
            check_prediction("01.4", guess, 0.0063, kind="order")


def test_prediction_authoring_mistakes_are_refused():
    with pytest.raises(ExerciseAuthoringError):
        check_prediction("01.4", NotAnswered, -0.1, kind="order")
    with pytest.raises(ExerciseAuthoringError):
        check_prediction("01.4", NotAnswered, float("nan"))
    with pytest.raises(ExerciseAuthoringError):
        check_prediction("01.4", NotAnswered, 1.0, kind="size")


# -------------------------------------------------------------------------------------- the inputs
def test_random_pose_shapes_and_identity():
    rot, off, par, root = random_pose(4, 6, 7)
    assert rot.shape == (6, 7, 4) and off.shape == (7, 3) and len(par) == 7 and root.shape == (6, 3)
    assert par[0] == -1 and all(0 <= p < j for j, p in enumerate(par) if j)
    assert torch.allclose(rot.norm(dim=-1), torch.ones(6, 7, dtype=torch.float64))
    rot, *_ = random_pose(4, 2, 7, identity=True)
    assert torch.equal(rot, R.quat_identity((2, 7), torch.float64))
    again = random_pose(4, 6, 7)
    assert torch.equal(again[0], random_pose(4, 6, 7)[0])


# ---------------------------------------------------------------------------------------- the labs
@pytest.mark.parametrize("which", ["right", "wrong", "not answered", "raises"])
def test_lab_shows_both_or_the_reference_alone(which, monkeypatch):

    drawn = _fake_animate(monkeypatch)
    args = random_pose(5, 12, 6)

    def wrong(rotations, offsets, parents, root):
        return fk(rotations, offsets * 2, parents, root)

    def raises(*a):
        raise KeyError("x")

    student = {"right": fk, "wrong": wrong, "not answered": NotAnswered, "raises": raises}[which]
    image = lab_animation("01.2", student, fk, args, args[2], every=4)
    assert image.format == "gif"
    assert len(drawn["frames"]) == 3
    if which in ("right", "wrong"):
        assert drawn["titles"] == ["library reference", f"your {student.__name__}"]
        ref, yours = (s.positions for s in drawn["frames"][1])
        assert np.allclose(ref, yours) == (which == "right")  # a wrong function looks wrong
    else:
        assert len(drawn["frames"][0]) == 1
        caption = drawn["titles"][0]
        assert caption.startswith("library reference alone")
        assert ("not answered yet" in caption) == (which == "not answered")
        assert ("KeyError" in caption) == (which == "raises")


# ------------------------------------------------------------ labs on a mesh, or on flagged joints
def _fake_animate(monkeypatch):
    import retarget_lib.notebook.exercises as ex

    drawn = {}

    def fake_animate(frames, path, fps, max_kb, titles, side_by_side, **kw):
        drawn.update(frames=frames, titles=titles)
        path.write_bytes(b"GIF89a")
        return path

    monkeypatch.setattr(ex, "animate", fake_animate)
    return drawn


def test_mesh_lab_draws_both_meshes(monkeypatch):
    drawn = _fake_animate(monkeypatch)
    rest = np.random.default_rng(0).normal(size=(5, 3))
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    shift = np.linspace(0.0, 1.0, 8)[:, None] * [1.0, 0.5, 0.0]

    def posed(shift):  # (T, V, 3) a mesh carried along a path
        return rest[None] + shift[:, None]

    def mirrored(shift):
        return posed(-shift)

    lab_animation("05.1", mirrored, posed, (shift,), None, faces=faces, every=2)
    assert len(drawn["frames"]) == 4
    ref, yours = drawn["frames"][1]
    assert ref.positions is None and np.array_equal(ref.faces, faces)
    assert ref.vertices.shape == (5, 3) and not np.allclose(ref.vertices, yours.vertices)
    lab_animation("05.1", NotAnswered, posed, (shift,), None, faces=faces, every=2)
    assert len(drawn["frames"][0]) == 1 and "not answered yet" in drawn["titles"][0]


@pytest.mark.parametrize("which", ["right", "wrong", "wrong shape"])
def test_flag_lab_colours_the_marked_joints(which, monkeypatch):
    drawn = _fake_animate(monkeypatch)
    args = random_pose(5, 12, 6)
    positions = fk(*args)

    def high(rotations, offsets, parents, root):  # (T, 2) flags of joints 1 and 2
        return fk(rotations, offsets, parents, root)[:, 1:3, 1].numpy() > 0

    student = {
        "right": high,
        "wrong": lambda *a: ~high(*a),
        "wrong shape": lambda *a: high(*a)[:, :1],
    }[which]
    lab_animation(
        "05b.1",
        student,
        high,
        args,
        args[2],
        to_positions=lambda flags: positions,
        marks=lambda flags: flags,
        marked=(1, 2),
        every=4,
    )
    if which == "wrong shape":
        assert len(drawn["frames"][0]) == 1
        assert "cannot be drawn" in drawn["titles"][0]
        return
    ref, yours = drawn["frames"][1]
    assert np.allclose(ref.positions, yours.positions)  # the same skeleton, other colours
    assert len(ref.vertices) % 2 == 0 and ref.scalars.shape == (len(ref.vertices),)
    balls = ref.vertices.reshape(2, -1, 3).mean(axis=1)
    assert np.allclose(balls, ref.positions[1:3])  # one ball on each marked joint
    expected = np.repeat(high(*args)[4], len(ref.vertices) // 2)
    assert np.array_equal(ref.scalars, expected)
    assert np.array_equal(yours.scalars, expected) == (which == "right")


# ------------------------------------------------------------------- labs of a whole pipeline
@pytest.mark.parametrize("which", ["right", "wrong", "not answered", "raises", "nan"])
def test_pipeline_lab_shows_both_or_the_reference_alone(which, monkeypatch):
    import retarget_lib.notebook.exercises as ex
    from retarget_lib.viz.scene import Scene

    drawn = {}

    def fake_animate(frames, path, fps, max_kb, titles, side_by_side, **kw):
        drawn.update(frames=frames, titles=titles, side_by_side=side_by_side)
        path.write_bytes(b"GIF89a")
        return path

    monkeypatch.setattr(ex, "animate", fake_animate)

    def energy(x):
        return (x - 1.0) ** 2

    def descend(fn, steps=5):
        """The pipeline: a few gradient steps on fn from x = 0, one point per step."""
        x, path = torch.zeros(3, requires_grad=True), []
        for _ in range(steps):
            (grad,) = torch.autograd.grad(fn(x).sum(), x)
            x = (x - 0.3 * grad).detach().requires_grad_(True)
            path.append(x.detach().numpy().copy())
        return path

    def to_scenes(path):
        return [Scene(positions=np.stack([p, p + 1.0]), parents=(-1, 0)) for p in path]

    def wrong(x):
        return -energy(x)

    def raises(x):
        raise KeyError("x")

    def nan(x):
        return energy(x) * float("nan")

    student = {
        "right": energy,
        "wrong": wrong,
        "not answered": NotAnswered,
        "raises": raises,
        "nan": nan,
    }[which]
    image = ex.pipeline_lab_animation("06.1", student, energy, descend, to_scenes)
    assert image.format == "gif"
    assert len(drawn["frames"]) == 5
    if which in ("right", "wrong"):
        assert drawn["titles"] == ["library reference", f"your {student.__name__}"]
        assert drawn["side_by_side"]
        ref, yours = (s.positions for s in drawn["frames"][-1])
        assert np.allclose(ref, yours) == (which == "right")  # a wrong function looks wrong
    else:
        assert len(drawn["frames"][0]) == 1 and not drawn["side_by_side"]
        caption = drawn["titles"][0]
        assert caption.startswith("library reference alone")
        assert ("not answered yet" in caption) == (which == "not answered")
        assert ("KeyError" in caption) == (which == "raises")
        assert ("cannot be drawn" in caption) == (which == "nan")


def test_pipeline_lab_refuses_a_reference_it_cannot_draw():
    import retarget_lib.notebook.exercises as ex

    with pytest.raises(ExerciseAuthoringError):
        ex.pipeline_lab_animation("06.1", NotAnswered, None, lambda fn: [], lambda r: r)
