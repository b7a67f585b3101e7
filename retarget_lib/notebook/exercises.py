"""Exercise checks and labs for the notebooks (docs/notebooks.md, "Writing an exercise").

A student cell begins with the line ``# exercise NN.K: your code here`` and holds a placeholder
until the student answers; the check cell after it calls one of

- :func:`check_function`: the student writes a function; it runs beside the library's reference on
  the notebook's own data and on random inputs (:func:`random_pose`), and the two results are
  compared (``numpy.allclose``, quaternions sign-free, or the exercise's own comparator);
- :func:`check_value`: the student computes a value; its reference may not be a constant a student
  could guess (:func:`assert_not_guessable`), and comes from the exercise's solution block
  (:func:`solution_value`) so that the notebook shows no answer;
- :func:`check_prediction`: "predict, then run": a direction (``"up"``, ``"down"``, ``"same"``) or
  an order of magnitude (a power of ten) against the change the cell measures;

and a lab (:func:`show_lab`) plugs the student's function into the real pipeline and shows it
animated beside the library's reference.

Every check prints one line and nothing taken from the reference:

- ``Exercise 01.2: not answered yet``: no exception, so a notebook runs to its end unanswered (CI
  executes the notebooks so);
- ``Exercise 01.2: correct``;
- or it raises :class:`ExerciseError`, one line naming the exercise and *why* the answer is wrong
  (the shape, (x, y, z, w) order, transposed matrices, centimetres or degrees, an identity input
  that does not give the identity, an exception of the student's function), never the expected
  value. Jupyter shows that line without a traceback.

**Not answered** (the one rule): the answer is still the student cell's placeholder, i.e. the value
:data:`NotAnswered`, or a function that raises ``NotImplementedError`` when called. Anything else
(``None``, ``...``, ``0``) is an answer and is judged.

Mistakes of the exercise's *author* (a reference a constant guess would match, too few cases, a
reference that raises) raise :class:`ExerciseAuthoringError` whether or not the student answered,
so the unanswered CI run catches them.
"""

from __future__ import annotations

import math
import re
import tempfile
import types
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import imageio.v3 as iio
import numpy as np
import torch
from IPython import display as ipython_display

from ..core.rotations import quat_from_axis_angle
from ..viz.animate import animate
from ..viz.display import MAX_KB, show
from ..viz.scene import Scene
from .book import NOTEBOOKS_DIR
from .solutions import read_solutions, solutions_file

__all__ = [
    "NotAnswered",
    "ExerciseError",
    "ExerciseAuthoringError",
    "Case",
    "GUESSES",
    "MIN_CASES",
    "check_function",
    "check_value",
    "solution_value",
    "check_prediction",
    "assert_not_guessable",
    "compare_arrays",
    "compare_quaternions",
    "compare_after",
    "is_not_answered",
    "random_pose",
    "lab_animation",
    "show_lab",
]

#: an exercise label: the notebook's number as in its file name, a dot, the exercise's number
LABEL = re.compile(r"^\d{2}[a-z]?\.\d+$")
#: the answers a student could guess without solving anything; no check may accept one
GUESSES: tuple[Any, ...] = (0, 1, -1, True, False, None, [])
#: a function exercise runs on the notebook's data and on at least three random inputs
MIN_CASES = 4
#: the directions a "predict, then run" exercise of kind ``"direction"`` accepts
DIRECTIONS = ("up", "down", "same")

#: ``(student result, reference result, the case's arguments) -> None`` when they agree, else the
#: reason they differ ("" when there is none to give)
Comparator = Callable[[Any, Any, tuple], str | None]


class _NotAnsweredType:
    """The placeholder of a student cell (one instance, :data:`NotAnswered`). Called as a function
    it raises ``NotImplementedError``, like an unwritten function."""

    _instance: _NotAnsweredType | None = None

    def __new__(cls) -> _NotAnsweredType:
        if cls._instance is None:
            cls._instance = super().__new__(cls)
        return cls._instance

    def __repr__(self) -> str:
        return "NotAnswered"

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise NotImplementedError("not answered yet")


#: what a student cell leaves in place of a value until the student answers
NotAnswered = _NotAnsweredType()


class ExerciseError(AssertionError):
    """A wrong answer: one line naming the exercise and why, never the expected value.

    ``_render_traceback_`` is how IPython shows an exception: the line alone, no traceback.
    """

    def _render_traceback_(self) -> list[str]:
        return [str(self)]


class ExerciseAuthoringError(ValueError):
    """An exercise that a guess could pass, or whose reference cannot answer its own cases."""


def is_not_answered(answer: Any) -> bool:
    """Whether ``answer`` is the placeholder :data:`NotAnswered` (also after the module was
    re-imported, which makes a new instance). A function is tested by calling it (see
    :func:`check_function`)."""
    return answer is NotAnswered or type(answer).__name__ == "_NotAnsweredType"


# ----------------------------------------------------------------------------------------- messages
def _check_label(label: str) -> None:
    if not isinstance(label, str) or not LABEL.match(label):
        raise ExerciseAuthoringError(f"exercise label {label!r} is not NN.K (e.g. '01.2', '08b.1')")


def _one_line(text: str, limit: int = 400) -> str:
    text = " ".join(part.strip() for part in str(text).splitlines() if part.strip())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _not_answered(label: str) -> None:
    print(f"Exercise {label}: not answered yet")


def _correct(label: str) -> None:
    print(f"Exercise {label}: correct")


def _wrong(label: str, why: str, hint: str, where: str = "") -> ExerciseError:
    why = why or "your result differs from the reference"
    text = f"Exercise {label}: wrong{' on ' + where if where else ''}: {why}"
    if hint and hint not in why:
        text += f"{'' if why.endswith(('.', '?', '!')) else '.'} Hint: {hint}"
    return ExerciseError(_one_line(text))


# --------------------------------------------------------------------------------------- comparison
def _as_array(x: Any) -> np.ndarray | str:
    """``x`` as a float array, or the reason it is not one (a message fragment)."""
    if x is None:
        return "it is None (a missing `return`?)"
    if isinstance(x, (bool, np.bool_)):
        return "it is True or False where numbers are expected"
    if isinstance(x, str):
        return "it is a string where numbers are expected"
    if isinstance(x, torch.Tensor):
        return x.detach().cpu().to(torch.float64).numpy()
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        return f"it is a {type(x).__name__}, not an array of numbers"
    return a


_ORDINAL = {0: "first", -1: "last"}


def _shape_why(got: tuple[int, ...], want: tuple[int, ...]) -> str:
    if len(got) != len(want):
        more = "more" if len(got) > len(want) else "fewer"
        return f"wrong shape: your result has {more} axes than the answer"
    if sorted(got) == sorted(want):
        return "wrong shape: the right sizes in another order of axes (transposed?)"
    bad = [i for i in range(len(want)) if got[i] != want[i]]
    names = sorted({_ORDINAL.get(i if i == 0 else i - len(want), "a middle") for i in bad})
    which = " and ".join(names)
    return f"wrong shape: the {which} axis has the wrong length"


def _close(a: np.ndarray, b: np.ndarray, rtol: float, atol: float, quaternion: bool) -> bool:
    if a.shape != b.shape:
        return False
    if not quaternion:
        return bool(np.allclose(a, b, rtol=rtol, atol=atol))
    # q and -q are the same rotation: each quaternion matches the reference with either sign
    same = np.isclose(a, b, rtol=rtol, atol=atol).all(-1)
    flipped = np.isclose(a, -b, rtol=rtol, atol=atol).all(-1)
    return bool((same | flipped).all())


#: results off by a known factor, and what the factor usually means
_FACTORS = (
    (100.0, "your result is a hundred times too large: centimetres where metres are expected?"),
    (1000.0, "your result is a thousand times too large: millimetres where metres are expected?"),
    (0.01, "your result is a hundred times too small: metres where centimetres are expected?"),
    (180.0 / math.pi, "your angles look like degrees where radians are expected"),
    (math.pi / 180.0, "your angles look like radians where degrees are expected"),
    (-1.0, "your result has the wrong sign (a direction reversed, or a product in another order?)"),
)


def _array_why(
    s: np.ndarray, r: np.ndarray, rtol: float, atol: float, quaternion: bool
) -> str | None:
    """``None`` when ``s`` matches ``r``, else why not (``""`` when no reason is recognised)."""
    if s.shape != r.shape:
        return _shape_why(s.shape, r.shape)
    if not np.all(np.isfinite(s)):
        return "your result has NaN or infinite values (a division by zero, arccos above one?)"
    if _close(s, r, rtol, atol, quaternion):
        return None
    if quaternion and s.shape[-1:] == (4,):
        if _close(s, r[..., [1, 2, 3, 0]], rtol, atol, True):
            return "your quaternions are in (x, y, z, w) order; the library's is (w, x, y, z)"
        if _close(s, r * np.array([1.0, -1.0, -1.0, -1.0]), rtol, atol, True):
            return (
                "your rotations are the inverse ones (conjugates): quat_mul(a, b) applies b first"
            )
        norms = np.linalg.norm(s, axis=-1)
        if not np.allclose(norms, 1.0, atol=1e-4):
            return "your quaternions are not of unit length: normalise them"
    if s.ndim >= 2 and s.shape[-1] == s.shape[-2] and s.shape[-1] > 1:
        if _close(s, np.swapaxes(r, -1, -2), rtol, atol, False):
            return (
                "your matrices are transposed: the library's act on column vectors, v' = R @ v "
                "(a row-vector formula gives the transpose)"
            )
    if np.any(r):
        if not np.any(s):
            return "your result is all zeros"
        shift = s - r
        if s.ndim >= 2 and s.shape[-2:] != (3, 3) and s.shape[-1] == 3 and s.shape[-2] > 1:
            if np.allclose(shift, shift[..., :1, :], rtol=rtol, atol=atol):
                return "every point is off by the same shift: check the root's position"
        for factor, why in _FACTORS:
            if _close(s, r * factor, rtol, atol, False):
                return why
    return ""


def _structure_why(
    s: Any, r: Any, rtol: float, atol: float, quaternion: bool, depth: int = 0
) -> str | None:
    """Compare nested tuples/lists of arrays or strings the same way, element by element."""
    if isinstance(r, str):
        if not isinstance(s, str):
            return "a name (a string) is expected"
        return None if s.strip() == r.strip() else ""
    if isinstance(r, tuple) and depth == 0:  # several results (a list is an array)
        if not isinstance(s, (tuple, list)):
            return "your result should be a tuple like the reference's (several results)"
        if len(s) != len(r):
            return "your result is a tuple of another length than the reference's"
        for k, (a, b) in enumerate(zip(s, r, strict=True)):
            why = _structure_why(a, b, rtol, atol, quaternion, depth + 1)
            if why is not None:
                which = "first" if k == 0 else "last" if k == len(r) - 1 else "a middle"
                return f"the {which} item of your tuple: {why or 'differs from the reference'}"
        return None
    if isinstance(r, (bool, np.bool_)):
        return None if isinstance(s, (bool, np.bool_)) and bool(s) == bool(r) else ""
    ra = _as_array(r)
    if isinstance(ra, str):
        return None if s == r else ""
    sa = _as_array(s)
    if isinstance(sa, str):
        return f"your result is not a number or an array: {sa}"
    return _array_why(sa, ra, rtol, atol, quaternion)


def compare_arrays(rtol: float = 1e-5, atol: float = 1e-6) -> Comparator:
    """The default comparison: same shape (no broadcasting) and ``numpy.allclose``; tuples item by
    item; strings equal once stripped. A mismatch says why when it recognises the mistake (shape,
    transposed matrices, a unit's factor, a flipped sign, zeros, NaN)."""

    def compare(student: Any, reference: Any, args: tuple = ()) -> str | None:
        return _structure_why(student, reference, rtol, atol, False)

    return compare


def compare_quaternions(rtol: float = 1e-5, atol: float = 1e-6) -> Comparator:
    """Like :func:`compare_arrays` for ``(..., 4)`` wxyz quaternions, sign-free (``q`` and ``-q``
    are the same rotation); recognises (x, y, z, w) order, conjugates and non-unit results."""

    def compare(student: Any, reference: Any, args: tuple = ()) -> str | None:
        return _structure_why(student, reference, rtol, atol, True)

    return compare


def compare_after(
    project: Callable[[Any, tuple], Any],
    why: str = "",
    rtol: float = 1e-5,
    atol: float = 1e-6,
) -> Comparator:
    """Compare what matters of two results: ``project(result, args)`` of each (e.g. the joint
    positions that some rotations give, when several rotations are right).

    The raw results must have the same shape and be finite first.

    Args:
        project: ``(result, the case's arguments) -> array`` (or a tuple of them).
        why: the reason to give when the projections differ (default: what the comparison of the
            projections recognises).
        rtol, atol: tolerances on the projections.
    """

    def compare(student: Any, reference: Any, args: tuple = ()) -> str | None:
        s, r = _as_array(student), _as_array(reference)
        if isinstance(s, str):
            return f"your result is not a number or an array: {s}"
        if isinstance(r, np.ndarray) and s.shape != r.shape:
            return _shape_why(s.shape, r.shape)
        if not np.all(np.isfinite(s)):
            return "your result has NaN or infinite values (a division by zero, arccos above one?)"
        if isinstance(student, np.ndarray) and isinstance(reference, torch.Tensor):
            student = torch.from_numpy(s)
        differs = _structure_why(
            project(student, args), project(reference, args), rtol, atol, False
        )
        return None if differs is None else (why or differs)

    return compare


def _comparator(compare: str | Comparator, rtol: float, atol: float) -> Comparator:
    if callable(compare):
        return compare
    if compare == "allclose":
        return compare_arrays(rtol, atol)
    if compare == "quaternion":
        return compare_quaternions(rtol, atol)
    raise ExerciseAuthoringError(
        f"compare must be 'allclose', 'quaternion' or a function, not {compare!r}"
    )


def _passes(comparator: Comparator, student: Any, reference: Any, args: tuple) -> bool:
    """Whether ``student`` would be judged right (a comparator that raises means no)."""
    try:
        return comparator(student, reference, args) is None
    except Exception:
        return False


def _guesses_for(reference: Any) -> list[Any]:
    """The constant guesses, plus arrays of the reference's shape filled with one of them."""
    out = list(GUESSES)
    ref = _as_array(reference) if not isinstance(reference, (tuple, str)) else None
    if isinstance(ref, np.ndarray) and ref.ndim > 0:
        out += [np.full(ref.shape, g, dtype=np.float64) for g in (0.0, 1.0, -1.0)]
    return out


def _is_guess(value: Any) -> bool:
    """Whether ``value`` is one of :data:`GUESSES` or an array filled with zero, one or minus
    one."""
    if value is None or isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, (list, tuple)) and len(value) == 0:
        return True
    a = _as_array(value)
    if isinstance(a, str):
        return False
    if a.size == 0:
        return True
    return bool(np.all(a == a.flat[0]) and a.flat[0] in (0.0, 1.0, -1.0))


def assert_not_guessable(
    reference: Any, compare: str | Comparator = "allclose", label: str = "", **tolerances: float
) -> None:
    """Refuse, at authoring time, an exercise whose answer a constant guess matches.

    Args:
        reference: the right answer.
        compare: how answers are compared (as in :func:`check_value`).
        label: the exercise, named in the error.
        **tolerances: ``rtol``/``atol`` for the built-in comparisons.

    Raises:
        ExerciseAuthoringError: ``reference`` is matched by 0, 1, -1, True, False, None, an empty
            list, or an array of the reference's shape filled with 0, 1 or -1.
    """
    comparator = _comparator(compare, tolerances.get("rtol", 1e-5), tolerances.get("atol", 1e-6))
    for guess in _guesses_for(reference):
        if _passes(comparator, guess, reference, ()):
            raise ExerciseAuthoringError(
                f"exercise {label or '?'}: the guess {_guess_name(guess)} matches the reference; "
                "ask for something a constant cannot answer"
            )


def _guess_name(guess: Any) -> str:
    if isinstance(guess, np.ndarray):
        return f"an array filled with {guess.flat[0]:g}"
    return repr(guess)


# ------------------------------------------------------------------------------------------- values
def check_value(
    label: str,
    value: Any,
    reference: Any,
    compare: str | Comparator = "allclose",
    hint: str = "",
    *,
    rtol: float = 1e-5,
    atol: float = 1e-6,
) -> None:
    """Judge a value the student computed.

    Args:
        label: the exercise, ``"NN.K"``.
        value: the student's answer (:data:`NotAnswered` until answered).
        reference: the right answer; a constant guess may not match it (checked first, whatever
            the student wrote: :func:`assert_not_guessable`).
        compare: ``"allclose"`` (arrays and numbers: same shape, ``numpy.allclose``; strings equal),
            ``"quaternion"`` (``(..., 4)`` wxyz, sign-free), or a comparator
            ``(value, reference, ()) -> None | why``.
        hint: one sentence for a student whose answer is wrong (never the answer).
        rtol, atol: tolerances of the built-in comparisons.

    Raises:
        ExerciseError: a wrong answer (a constant guess always is).
        ExerciseAuthoringError: a guessable reference.
    """
    _check_label(label)
    comparator = _comparator(compare, rtol, atol)
    assert_not_guessable(reference, comparator, label)
    if is_not_answered(value):
        _not_answered(label)
        return
    if _is_guess(value):
        raise _wrong(
            label,
            "a constant guess (zero, one, minus one, True, False, None, empty) is never the "
            "answer here",
            hint,
        )
    try:
        why = comparator(value, reference, ())
    except Exception as e:  # a custom comparator choking on a strange answer
        why = f"your answer cannot be compared ({type(e).__name__})"
    if why is None:
        _correct(label)
        return
    raise _wrong(label, why, hint)


def solution_value(label: str, name: str, namespace: Mapping[str, Any]) -> Any:
    """The value the reference answer of exercise ``label`` gives ``name``: its block of
    ``notebooks/solutions/`` run in a copy of the notebook's namespace (``globals()`` in a
    cell), so the student's own variables stay as they are.

    A block used so must not change the notebook's objects in place.

    Raises:
        ExerciseAuthoringError: no solutions file or block for ``label``, or the block does not
            set ``name``.
    """
    number = label.split(".", 1)[0]
    files = [solutions_file(nb) for nb in sorted(NOTEBOOKS_DIR.glob(f"{number}_*.ipynb"))]
    if len(files) != 1 or not files[0].exists():
        raise ExerciseAuthoringError(f"exercise {label}: no solutions/{number}_*.py")
    code = read_solutions(files[0]).get(label)
    if code is None:
        raise ExerciseAuthoringError(f"exercise {label}: no block in {files[0].name}")
    scratch = dict(namespace)
    exec(compile(code, f"<solution {label}>", "exec"), scratch)
    if name not in scratch:
        raise ExerciseAuthoringError(f"exercise {label}: its solution does not set {name}")
    return scratch[name]


# ---------------------------------------------------------------------------------------- functions
@dataclass(frozen=True)
class Case:
    """One input of a function exercise.

    Attributes:
        args: the positional arguments (a tuple), or a function of no arguments returning them
            (built when the check runs).
        name: how a message names this input ("the CMU clip", "a random tree").
        hint: why a function fails on this input when it does (the identity input: "with identity
            rotations every joint stays at its rest position").
    """

    args: tuple | Callable[[], tuple]
    name: str = "one of the test inputs"
    hint: str = ""

    def build(self) -> tuple:
        args = self.args() if callable(self.args) else self.args
        if not isinstance(args, tuple):
            raise ExerciseAuthoringError(f"case {self.name!r}: arguments must be a tuple")
        return args


def _copied(x: Any) -> Any:
    """A copy of arguments that a function could change in place (tensors, arrays, lists)."""
    if isinstance(x, torch.Tensor):
        return x.clone()
    if isinstance(x, np.ndarray):
        return x.copy()
    if isinstance(x, tuple):
        return tuple(_copied(v) for v in x)
    if isinstance(x, list):
        return [_copied(v) for v in x]
    if isinstance(x, dict):
        return {k: _copied(v) for k, v in x.items()}
    return x


def _names_used(fn: Any) -> set[str]:
    """Global and attribute names a function's code (and its nested functions') refers to."""
    code = getattr(fn, "__code__", None)
    names: set[str] = set()
    todo = [code] if code is not None else []
    while todo:
        c = todo.pop()
        names |= set(c.co_names)
        todo += [k for k in c.co_consts if isinstance(k, types.CodeType)]
    return names


def _same_everywhere(outputs: list[Any]) -> bool:
    """Whether a function gave the same result for every input."""
    arrays = []
    for o in outputs:
        a = None if isinstance(o, tuple) else _as_array(o)
        if not isinstance(a, np.ndarray):
            return False
        arrays.append(a)
    first = arrays[0]
    return all(a.shape == first.shape and np.array_equal(a, first) for a in arrays[1:])


def check_function(
    label: str,
    student_fn: Any,
    reference_fn: Callable[..., Any],
    cases: Sequence[tuple | Callable[[], tuple] | Case],
    compare: str | Comparator = "allclose",
    hint: str = "",
    *,
    rtol: float = 1e-5,
    atol: float = 1e-6,
    forbid: Sequence[str] = (),
    quaternion_args: Sequence[int] = (),
) -> None:
    """Judge a function the student wrote against the library's reference.

    Both functions are called on every case (each on its own copy of the arguments) and their
    results compared. The cases are the notebook's own data and at least three random inputs
    (:func:`random_pose`): other shapes, other seeds, edge cases such as identity rotations.

    Args:
        label: the exercise, ``"NN.K"``.
        student_fn: the student's function (a function raising ``NotImplementedError``, or
            :data:`NotAnswered`, until answered).
        reference_fn: the library's answer, same arguments.
        cases: at least :data:`MIN_CASES`: argument tuples, functions returning them, or
            :class:`Case` (with a name and a hint).
        compare: ``"allclose"``, ``"quaternion"`` (sign-free wxyz) or a comparator
            ``(student result, reference result, args) -> None | why`` (``""``: no reason known).
        hint: one sentence for a student whose function is wrong (never a value).
        rtol, atol: tolerances of the built-in comparisons.
        forbid: names the student's function may not use (the library function it re-implements).
        quaternion_args: positions of the arguments that hold wxyz quaternions: a wrong result is
            also compared with the reference's on those quaternions read as (x, y, z, w) and on
            their inverses (a transposed matrix), to say which convention the student broke.

    Raises:
        ExerciseError: the function's result differs on a case, or the function raised.
        ExerciseAuthoringError: fewer than :data:`MIN_CASES` cases, a reference that raises, or
            cases whose answers a constant function could give.
    """
    _check_label(label)
    comparator = _comparator(compare, rtol, atol)
    given = [c if isinstance(c, Case) else Case(c) for c in cases]
    if len(given) < MIN_CASES:
        raise ExerciseAuthoringError(
            f"exercise {label}: {len(given)} cases; give the notebook's data and at least three "
            "random inputs"
        )
    built = [(case, case.build()) for case in given]
    references = []
    for case, args in built:
        try:
            references.append(reference_fn(*_copied(args)))
        except Exception as e:
            raise ExerciseAuthoringError(
                f"exercise {label}: the reference raised {type(e).__name__} on {case.name}: {e}"
            ) from e
    _assert_function_check_can_fail(label, comparator, built, references)
    if is_not_answered(student_fn):
        _not_answered(label)
        return
    if not callable(student_fn):
        raise _wrong(label, f"a function is expected, not a {type(student_fn).__name__}", hint)
    used = sorted(_names_used(student_fn) & set(forbid))
    if used:
        raise _wrong(label, f"write it without {', '.join(used)} (that is the exercise)", hint)
    outputs: list[Any] = []
    failures: list[tuple[Case, tuple, Any, str]] = []  # (case, its arguments, result, why)
    for k, ((case, args), reference) in enumerate(zip(built, references, strict=True)):
        try:
            out = student_fn(*_copied(args))
        except NotImplementedError:
            if k == 0:
                _not_answered(label)
                return
            raise _wrong(
                label, "your function raised NotImplementedError", hint, case.name
            ) from None
        except Exception as e:  # its type only: the message may quote sizes of the input
            why = f"your function raised {type(e).__name__}"
            raise _wrong(label, why, hint or case.hint, case.name) from None
        outputs.append(out)
        try:
            differs = comparator(out, reference, args)
        except Exception as e:
            differs = f"its result cannot be compared ({type(e).__name__})"
        if differs is not None:
            failures.append((case, args, out, differs))
    if not failures:
        _correct(label)
        return
    if _same_everywhere(outputs):
        raise _wrong(label, "your function returns the same result whatever its input", hint)
    if quaternion_args:
        for case, args, out, _ in failures:
            convention = _input_convention(reference_fn, comparator, args, out, quaternion_args)
            if convention:
                raise _wrong(label, convention, hint, case.name)
    case, _, _, why = next((f for f in failures if f[3]), failures[0])
    if not why:  # no mistake recognised: the case's own hint, if one of the failing cases has one
        hinted = next((f[0] for f in failures if f[0].hint), None)
        if hinted is not None:
            case, why = hinted, hinted.hint
    raise _wrong(label, why, hint, case.name)


#: how a student may misread the quaternions given to a function, and what that mistake is
_INPUT_CONVENTIONS: tuple[tuple[Callable[[Any], Any], str], ...] = (
    (
        lambda q: q[..., [3, 0, 1, 2]],
        "you read the quaternions as (x, y, z, w); the library's are (w, x, y, z)",
    ),
    (
        lambda q: (
            q * q.new_tensor([1.0, -1.0, -1.0, -1.0])
            if isinstance(q, torch.Tensor)
            else q * np.array([1.0, -1.0, -1.0, -1.0])
        ),
        "you turn by the inverse rotations: a transposed matrix (the library's act on column "
        "vectors, v' = R @ v) or a product in the other order (quat_mul(a, b) applies b first)",
    ),
)


def _input_convention(
    reference_fn: Callable[..., Any],
    comparator: Comparator,
    args: tuple,
    out: Any,
    quaternion_args: Sequence[int],
) -> str:
    """Which misreading of the quaternion arguments gives the student's result ("" if none)."""
    for misread, why in _INPUT_CONVENTIONS:
        changed = tuple(
            misread(a) if i in quaternion_args else a for i, a in enumerate(_copied(args))
        )
        try:
            if comparator(out, reference_fn(*changed), changed) is None:
                return why
        except Exception:
            continue
    return ""


def _assert_function_check_can_fail(
    label: str, comparator: Comparator, built: list[tuple[Case, tuple]], references: list[Any]
) -> None:
    """A function returning a constant guess, or always the first case's answer, must fail."""
    for guess in GUESSES:
        if all(
            _passes(comparator, guess, r, a) for (_, a), r in zip(built, references, strict=True)
        ):
            raise ExerciseAuthoringError(
                f"exercise {label}: a function returning {guess!r} passes every case"
            )
    for fill in (0.0, 1.0, -1.0):
        filled = []
        for r in references:
            ra = _as_array(r) if not isinstance(r, (tuple, str)) else None
            filled.append(np.full(ra.shape, fill) if isinstance(ra, np.ndarray) else None)
        if all(
            f is not None and _passes(comparator, f, r, a)
            for f, (_, a), r in zip(filled, built, references, strict=True)
        ):
            raise ExerciseAuthoringError(
                f"exercise {label}: a function returning arrays filled with {fill:g} passes every "
                "case"
            )
    first = references[0]
    if all(_passes(comparator, first, r, a) for (_, a), r in zip(built, references, strict=True)):
        raise ExerciseAuthoringError(
            f"exercise {label}: every case has the same answer, so a constant function passes; "
            "give inputs whose answers differ"
        )


# -------------------------------------------------------------------------------------- predictions
def check_prediction(
    label: str,
    predicted: Any,
    measured: Any,
    kind: str = "direction",
    hint: str = "",
    *,
    tolerance: float = 1e-9,
) -> None:
    """Predict, then run: judge the student's prediction against what the cell measured.

    Args:
        label: the exercise, ``"NN.K"``.
        predicted: the student's prediction (:data:`NotAnswered` until answered). For
            ``kind="direction"``: ``"up"``, ``"down"`` or ``"same"`` (case and spaces ignored).
            For ``kind="order"``: the integer ``k`` such that the change is about ``10**k`` (in the
            unit the exercise names).
        measured: the change the cell measured: signed (after minus before) for a direction, a
            positive magnitude for an order.
        kind: ``"direction"`` (``"same"`` when ``|measured| <= tolerance``) or ``"order"`` (the
            power of ten nearest to ``measured`` on a log scale, ``round(log10(measured))``).
        hint: one sentence for a wrong prediction.
        tolerance: below it a change counts as ``"same"``.

    Raises:
        ExerciseError: a wrong prediction (it says which way the measurement went, never its
            value).
        ExerciseAuthoringError: an unknown ``kind``, or a measurement that is not a finite number
            (not positive, for an order).
    """
    _check_label(label)
    if kind not in ("direction", "order"):
        raise ExerciseAuthoringError(f"exercise {label}: kind must be 'direction' or 'order'")
    m = _as_array(measured)
    if isinstance(m, str) or m.size != 1 or not np.isfinite(m).all():
        raise ExerciseAuthoringError(f"exercise {label}: the measurement must be one finite number")
    value = float(m.reshape(()))
    if kind == "order" and value <= 0:
        raise ExerciseAuthoringError(f"exercise {label}: an order of magnitude needs a size > 0")
    if is_not_answered(predicted):
        _not_answered(label)
        return
    if kind == "direction":
        truth = "same" if abs(value) <= tolerance else ("up" if value > 0 else "down")
        if not isinstance(predicted, str) or predicted.strip().lower() not in DIRECTIONS:
            raise _wrong(label, "predict with one of the words 'up', 'down' or 'same'", hint)
        guess = predicted.strip().lower()
        if guess == truth:
            _correct(label)
            return
        went = {"up": "it went up", "down": "it went down", "same": "it did not change"}[truth]
        raise _wrong(label, f"{went}, not {guess!r}", hint)
    if isinstance(predicted, (bool, np.bool_)) or not isinstance(
        predicted, (int, float, np.integer, np.floating)
    ):
        raise _wrong(label, "predict with an integer: the power of ten", hint)
    if not float(predicted).is_integer():
        raise _wrong(
            label, "predict the power of ten (an integer exponent), not the value itself", hint
        )
    truth_k = math.floor(math.log10(value) + 0.5)
    if int(predicted) == truth_k:
        _correct(label)
        return
    size = "smaller" if truth_k < int(predicted) else "larger"
    raise _wrong(label, f"the measured change is {size} than your prediction", hint)


# ------------------------------------------------------------------------------------ random inputs
def random_pose(
    seed: int,
    frames: int,
    joints: int = 8,
    *,
    offsets: Any = None,
    parents: Sequence[int] | None = None,
    identity: bool = False,
    max_degrees: float = 180.0,
) -> tuple[torch.Tensor, torch.Tensor, tuple[int, ...], torch.Tensor]:
    """Random forward-kinematics inputs (float64) for the checks' random cases.

    Args:
        seed: the seed (each case its own, so a check is the same on every run).
        frames: ``T``.
        joints: ``J`` of a random tree (each joint's parent drawn among the earlier joints, bones
            of 5 to 40 cm in random directions); ignored when ``offsets`` and ``parents`` are given.
        offsets: ``(J, 3)`` a skeleton's rest offsets to use instead of a random tree.
        parents: its ``J`` parents.
        identity: every local rotation the identity (the skeleton stands in its rest pose).
        max_degrees: each local rotation turns by at most this much about a random axis.

    Returns:
        ``(rotations (T, J, 4) unit wxyz, offsets (J, 3), parents, root_positions (T, 3))``.
    """
    rng = np.random.default_rng(seed)
    if offsets is None or parents is None:
        par = [-1] + [int(rng.integers(0, j)) for j in range(1, joints)]
        d = rng.normal(size=(joints, 3))
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        off = d * rng.uniform(0.05, 0.4, size=(joints, 1))
        off[0] = rng.normal(scale=0.5, size=3)
    else:
        par = [int(p) for p in parents]
        off = np.asarray(offsets, dtype=np.float64)
    n = len(par)
    axis = rng.normal(size=(frames, n, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = rng.uniform(0.0, np.radians(max_degrees), size=(frames, n, 1)) * (not identity)
    rotations = quat_from_axis_angle(torch.from_numpy(axis * angle))
    root = torch.from_numpy(rng.normal(scale=1.0, size=(frames, 3)))
    return rotations, torch.from_numpy(off.copy()), tuple(par), root


# --------------------------------------------------------------------------------------------- labs
def _positions(x: Any) -> np.ndarray | None:
    a = _as_array(x)
    if isinstance(a, str) or a.ndim != 3 or a.shape[-1] != 3 or not np.all(np.isfinite(a)):
        return None
    return a


def lab_animation(
    label: str,
    student_fn: Any,
    reference_fn: Callable[..., Any],
    args: tuple,
    parents: Sequence[int] | None,
    to_positions: Callable[[Any], Any] | None = None,
    frames: slice = slice(None),
    target: Any = None,
    every: int = 4,
    fps: float = 30.0,
    centre: bool = True,
    view: str = "front_side",
    window_size: tuple[int, int] = (420, 260),
    max_kb: float = MAX_KB,
    faces: Any = None,
    marks: Callable[[Any], Any] | None = None,
    marked: Sequence[int] = (),
) -> Any:
    """The student's function in the real pipeline, animated beside the library's reference.

    Both functions run on the same real input (``args``, e.g. a CMU clip); their results become
    joint positions (``to_positions``) drawn side by side as a looping GIF: a wrong function shows
    wrong motion. When the student's function is not answered, raises, or gives something that
    cannot be drawn, the reference plays alone and its caption says why. Never raises for the
    student's sake (the check after it does).

    Args:
        label: the exercise, ``"NN.K"``.
        student_fn: the student's function (or :data:`NotAnswered`).
        reference_fn: the library's function, same arguments.
        args: the real input.
        parents: ``J`` parents of the drawn skeleton.
        to_positions: a result -> ``(T, J, 3)`` joint positions (default: the result is that).
        frames: the frames shown (a slice of ``T``), every ``every``-th of them.
        target: ``(T, 3)`` a point drawn in both pictures (e.g. an IK target), or ``None``.
        every: frame step; fps: the input's frame rate.
        centre: keep the character in view: the reference's root is moved to ``x = z = 0`` in
            every frame (the same shift for both, so a wrong root still shows).
        view: camera preset; window_size: ``(width, height)``; max_kb: GIF size budget.
        faces, marks, marked: a mesh or flagged joints (:func:`_lab_scene`): ``faces`` ``(F, 3)``
            makes ``to_positions`` give ``(T, V, 3)`` mesh vertices (``parents`` unused);
            ``marks`` gives a result's ``(T, K)`` flags of the ``K`` joints ``marked``.

    Returns:
        an ``IPython.display.Image`` (the GIF; the first frame as PNG if it cannot fit).
    """
    _check_label(label)
    convert = to_positions or (lambda x: x)
    reference_out = reference_fn(*_copied(args))
    reference = _positions(convert(reference_out))
    if reference is None:
        raise ExerciseAuthoringError(
            f"exercise {label}: the reference gives no (T, J, 3) positions"
        )
    reference_flags = _lab_flags(marks, reference_out, reference, marked)
    if marks is not None and reference_flags is None:
        raise ExerciseAuthoringError(f"exercise {label}: the reference gives no (T, K) flags")
    name = getattr(student_fn, "__name__", "function")
    student, student_flags, why = None, None, ""
    if is_not_answered(student_fn):
        why = "is not answered yet"
    else:
        try:
            student_out = student_fn(*_copied(args))
            student = _positions(convert(student_out))
            student_flags = _lab_flags(marks, student_out, student, marked)
            if (
                student is None
                or student.shape != reference.shape
                or (marks is not None and student_flags is None)
            ):
                student, why = None, "gives a result that cannot be drawn"
        except NotImplementedError:
            why = "is not answered yet"
        except Exception as e:
            why = f"raised {type(e).__name__}"
    shift = np.zeros_like(reference[:, :1])
    if centre:
        anchor = reference.mean(axis=1, keepdims=True) if faces is not None else reference[:, :1]
        shift[..., [0, 2]] = -anchor[..., [0, 2]]
    goal = None if target is None else _as_array(target)
    shown = range(len(reference))[frames][:: max(1, every)]
    draws = [reference] + ([student] if student is not None else [])
    flags = [reference_flags, student_flags]
    radius = 0.04 * float(np.ptp(reference[0], axis=0).max())
    titles = (
        ["library reference", f"your {name}"]
        if student is not None
        else [f"library reference alone: your {name} {why}"]
    )
    scenes = []
    for t in shown:
        pairs = None
        if isinstance(goal, np.ndarray):
            point = goal[t] + shift[t, 0]
            pairs = np.stack([point, point])[None]
        scenes.append(
            [
                _lab_scene(p[t] + shift[t], parents, pairs, faces, marked, f, t, radius)
                for p, f in zip(draws, flags[: len(draws)], strict=True)
            ]
        )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"exercise_{label}.gif"
        animate(
            scenes,
            path,
            fps=fps / max(1, every),
            max_kb=max_kb,
            titles=titles,
            side_by_side=len(draws) > 1,
            view=view,
            window_size=window_size,
        )
        data = path.read_bytes()
    if len(data) > max_kb * 1024:
        return show(iio.imread(data, index=0)[..., :3], max_kb)
    return ipython_display.Image(data=data, format="gif")


def show_lab(*args: Any, **kwargs: Any) -> None:
    """Display :func:`lab_animation` (same arguments) in the notebook."""
    ipython_display.display(lab_animation(*args, **kwargs))


# ------------------------------------------------------------- labs on a mesh, or on flagged joints
# A lab whose result is a skinned mesh (notebook 05: ``faces``) or per-joint flags such as foot
# contacts (notebook 05b: ``marks`` and ``marked``); :func:`lab_animation` draws each picture with
# :func:`_lab_scene`.

#: the colours of a marked joint's ball: its flag not set, set (e.g. a foot off / on the ground)
MARK_COLORS = ("#d0d0d0", "#2ca02c")


def _ball(rings: int = 5, segments: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A unit sphere: ``(N, 3)`` vertices and ``(F, 3)`` counter-clockwise triangles."""
    polar = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    azimuth = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack(
        [
            np.sin(polar)[:, None] * np.cos(azimuth),
            np.repeat(np.cos(polar)[:, None], segments, 1),
            np.sin(polar)[:, None] * np.sin(azimuth),
        ],
        axis=-1,
    ).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]])
    bottom = len(vertices) - 1
    faces = []
    for a in range(segments):
        b = (a + 1) % segments
        faces.append((0, 1 + b, 1 + a))
        for r in range(rings - 2):
            p, q = 1 + r * segments, 1 + (r + 1) * segments
            faces += [(p + a, p + b, q + a), (p + b, q + b, q + a)]
        last = 1 + (rings - 2) * segments
        faces.append((bottom, last + a, last + b))
    return vertices, np.asarray(faces, dtype=np.int64)


def _lab_flags(
    marks: Callable[[Any], Any] | None, result: Any, positions: Any, marked: Sequence[int]
) -> np.ndarray | None:
    """``(T, K)`` bool flags ``marks(result)`` of the ``K`` joints ``marked``, or ``None`` (no
    ``marks``, or flags that cannot be drawn: another shape, not numbers, an exception)."""
    if marks is None or positions is None:
        return None
    try:
        a = _as_array(marks(result))
    except Exception:
        return None
    if isinstance(a, str) or a.shape != (len(positions), len(marked)) or not np.isfinite(a).all():
        return None
    return a != 0


def _lab_scene(
    points: np.ndarray,
    parents: Sequence[int] | None,
    pairs: np.ndarray | None,
    faces: Any,
    marked: Sequence[int],
    flags: np.ndarray | None,
    t: int,
    radius: float,
) -> Scene:
    """One picture of a lab at frame ``t``: a mesh (``faces`` given: ``points`` are its vertices),
    else a skeleton with, when ``flags`` are given, a ball at each joint of ``marked`` coloured by
    its flag at ``t`` (:data:`MARK_COLORS`); ``pairs``: the target point, if any."""
    if faces is not None:
        return Scene(vertices=points, faces=faces, point_pairs=pairs, pair_radius=0.03)
    if flags is None or not len(marked):
        return Scene(positions=points, parents=parents, point_pairs=pairs, pair_radius=0.03)
    ball, ball_faces = _ball()
    return Scene(
        positions=points,
        parents=parents,
        point_pairs=pairs,
        pair_radius=0.03,
        vertices=(points[list(marked)][:, None] + radius * ball).reshape(-1, 3),
        faces=(ball_faces + len(ball) * np.arange(len(marked))[:, None, None]).reshape(-1, 3),
        scalars=np.repeat(flags[t].astype(np.float64), len(ball)),
        cmap=cast(Any, list(MARK_COLORS)),  # two colours: PyVista takes a list as a colormap
        clim=(0.0, 1.0),
        mesh_opacity=1.0,
    )


# ------------------------------------------------------------------- labs of a whole pipeline
# (notebooks 06, 07 and 07b) A lab whose picture is not the skeleton one function returns but a
# pipeline run with the student's function plugged in (gradient steps on the student's energy, a
# root path optimised with it, a few ESO iterations with the student's step), drawn as any scenes:
# meshes, skeletons, contact pairs.
__all__ += ["pipeline_lab_animation", "show_pipeline_lab"]


def _drawable(frames: Any, count: int | None = None) -> bool:
    """Whether ``frames`` is a list of scenes (``count`` of them, when given) with finite points,
    as many in every frame."""
    if not isinstance(frames, (list, tuple)) or not frames:
        return False
    if count is not None and len(frames) != count:
        return False
    shapes = set()
    for scene in frames:
        if not isinstance(scene, Scene):
            return False
        points = np.asarray(scene.points(), dtype=np.float64)
        if not np.all(np.isfinite(points)):
            return False
        shapes.add(points.shape)
    return len(shapes) == 1


def pipeline_lab_animation(
    label: str,
    student_fn: Any,
    reference_fn: Callable[..., Any],
    run: Callable[[Callable[..., Any]], Any],
    to_scenes: Callable[[Any], Sequence[Scene]],
    *,
    fps: float = 8.0,
    view: Any = "front",
    window_size: tuple[int, int] = (460, 300),
    stand: bool = False,
    max_kb: float = MAX_KB,
) -> Any:
    """The student's function at work in a pipeline, animated beside the library's.

    Like :func:`lab_animation`, for what a skeleton of the function's own result cannot show: the
    pipeline ``run`` is executed once with the library's function and once with the student's,
    and each result becomes one scene per animation frame (``to_scenes``; a mesh, a skeleton,
    contact pairs), drawn side by side as a looping GIF. When the student's function is not
    answered, raises (in the pipeline or while drawing), or gives something that cannot be drawn
    (NaN, another number of frames), the reference plays alone and its caption says why. Never
    raises for the student's sake (the check after it does).

    Args:
        label: the exercise, ``"NN.K"``.
        student_fn: the student's function (or :data:`NotAnswered`).
        reference_fn: the library's function, same signature.
        run: ``fn -> result``, the pipeline with ``fn`` plugged in (e.g. gradient steps on the
            energy ``fn`` computes).
        to_scenes: ``result -> [Scene, ...]``, one scene per animation frame, the same structure
            (vertex and face counts, which attributes are set) in every frame; a scene's
            ``scalars`` may change from frame to frame, its ``highlight_faces`` may not.
        fps: playback rate; view: camera preset or ``(azimuth, elevation)``; window_size:
            ``(width, height)``; stand: put each side's lowest point on the floor; max_kb: GIF
            size budget.

    Returns:
        an ``IPython.display.Image`` (the GIF; the first frame as PNG if it cannot fit).
    """
    _check_label(label)
    reference = list(to_scenes(run(reference_fn)))
    if not _drawable(reference):
        raise ExerciseAuthoringError(
            f"exercise {label}: the reference pipeline gives no scenes with finite points"
        )
    name = getattr(student_fn, "__name__", "function")
    student, why = None, ""
    if is_not_answered(student_fn):
        why = "is not answered yet"
    else:
        try:
            student = list(to_scenes(run(student_fn)))
            if not _drawable(student, len(reference)):
                student, why = None, "gives a result that cannot be drawn"
        except NotImplementedError:
            student, why = None, "is not answered yet"
        except Exception as e:
            student, why = None, f"raised {type(e).__name__}"
    titles = (
        ["library reference", f"your {name}"]
        if student is not None
        else [f"library reference alone: your {name} {why}"]
    )
    frames = [
        [r] if student is None else [r, s]
        for r, s in zip(reference, student or reference, strict=True)
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"exercise_{label}.gif"
        animate(
            frames,
            path,
            fps=fps,
            max_kb=max_kb,
            titles=titles,
            side_by_side=student is not None,
            view=view,
            window_size=window_size,
            stand=stand,
        )
        data = path.read_bytes()
    if len(data) > max_kb * 1024:
        return show(iio.imread(data, index=0)[..., :3], max_kb)
    return ipython_display.Image(data=data, format="gif")


def show_pipeline_lab(*args: Any, **kwargs: Any) -> None:
    """Display :func:`pipeline_lab_animation` (same arguments) in the notebook."""
    ipython_display.display(pipeline_lab_animation(*args, **kwargs))
