"""Lint for the notebooks' Markdown: no hand-typed result numbers, and the closing sections.

**The rule.** A measured value in a notebook's prose goes stale the day a checkpoint changes, so the
Markdown *source* cells (not the rendered outputs of ``prose(...)``, which are computed) may not
contain a number of one of these kinds:

- a **decimal**: ``0.58``, ``1.2e-3``;
- a **percentage**: ``10%``, ``10 %``;
- a **ratio**: ``3x``, ``649×``, ``0.6x-649x``;
- a **number with a unit**: length (``mm cm m km``), time (``ms s sec min h`` and the words),
  angle (``°``, ``deg``, ``degrees``), rate (``fps Hz``), size (``KB MB GB KiB MiB GiB``),
  training amounts (``steps iterations epochs frames``, also hyphenated: ``81-frame``), and the
  multipliers ``k``/``M`` (``100k``).

Bare integers (``22 joints``, ``16 characters``), years and version-like names are not flagged.

**What is allowed**, removed before the scan:

1. *References*: ``Eq. 8``, ``Eqs. 4-8``, ``Sec. 3.4``, ``Section 5``, ``Table 4``, ``Fig. 3``,
   ``Figure 5b``, ``App. F``, ``Appendix B.2``, ``Alg. 1``, ``notebook 04``, ``Exercise 05.2``; and
   an exercise label on its own when written with the notebook number's leading zero (``your 08.1
   answer``, ``08b.2``): a measured decimal is never written so.
2. *Code*: inline code in backticks (config constants such as ```lambda_h = 10```,
   ```train.steps=2000```) and fenced code blocks; HTML comments and tags; link targets and URLs.
3. *Versions* after a known name: ``glTF 2.0``, ``Python 3.11``, ``assimp 5.2.5``, ``MathJax 3.2``.
4. *Sentences that cite a paper*: a sentence (split at ``.``/``!``/``?`` followed by a capital,
   and at paragraph, list-item, table-row and heading breaks; a display equation ``$$...$$`` in a
   paragraph of its own belongs to the sentence before it) is a citation, and every number in it
   allowed, when it contains

   - a parenthesis holding a paper location: ``(Sec. 5)``, ``(Kim et al. 2020, Eq. 6)``,
     ``(Appendix F)``, ``(Fig. 3)`` — but not ``(Table 4)`` alone, since our own tables are
     called that too; or
   - the word *paper* (``paper``, ``papers``, ``paper's``) together with a location reference
     anywhere in the sentence: ``the paper's Table 4 reports 0.58``.

5. *Library conventions* (:data:`LIBRARY_CONSTANTS`), allowed in every notebook: the canonical
   frame rate ``30 fps``. Each is a token beside the code that defines it, and a test checks the
   two agree, so the prose cannot drift from the library.
6. *An explicit allowlist* for constants of the papers that need none of the above: an HTML comment
   in the cell, ``<!-- constants: 100k, 0.5, 15 cm -->``; each listed token (compared without
   spaces) is allowed in that cell only.

A number that survives is a *violation*: render it from the computed value with
``prose(f"... {value:.2f} ...")``, cite the paper, or list it as a constant.

**The closing sections** (:func:`section_problems`): every notebook has ``## Summary`` (with a line
``Equations covered: ...``), ``## Exercises`` and ``## References`` headings, in that order, as its
last ``##`` sections; between Exercises and References, 3-5 exercises labelled ``**Exercise N.k**``
(N the notebook's number as in its file name), each followed, before the next exercise, by a
student cell whose first line is ``# exercise N.k: your code here`` (docs/notebooks.md, "Writing an
exercise") and, after it, a code cell calling ``check_function``, ``check_value`` or
``check_prediction`` with ``"N.k"``; no cell tagged ``solution`` (the answers live in
``notebooks/solutions/``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from .solutions import STUDENT_HEADER

__all__ = ["Violation", "scan_markdown", "notebook_violations", "section_problems"]

_NUM = r"\d+(?:[.,]\d+)*"
_REF_WORDS = (
    r"Eqs?|Equations?|Secs?|Sections?|§|Tables?|Tabs?|Figs?|Figures?|Apps?|Appendix|Appendices"
    r"|Algs?|Algorithms?|[Nn]otebooks?|Exercises?|Rows?|Scenarios?"
)
_REF_ITEM = r"(?:\d+(?:\.\d+)*[a-z]?|[A-Z](?:\.\d+)*)"
#: "Eq. 8", "Eqs. 4-8", "Sec. 3.4", "Table 4", "Figure 5b", "Appendix F", "notebook 04", "Exercise
#: 05.2"
REFERENCE = re.compile(
    rf"\b(?i:{_REF_WORDS})\.?\s*{_REF_ITEM}"
    rf"(?:\s*(?:[-–—/]|to)\s*{_REF_ITEM}|\s*(?:,|and|&)\s*(?:\d+[a-z]?|[A-Z])(?![\d.]))*"
)
#: a parenthesis holding a location in a paper (not "Table" alone: ours are called that too)
PAREN_CITATION = re.compile(
    r"\([^()]*\b(?:Eqs?|Equations?|Secs?|Sections?|§|Figs?|Figures?|Apps?|Appendix|Algs?)"
    r"\.?\s*[\dA-Z][^()]*\)"
)
PAPER_WORD = re.compile(r"\bpapers?(?:'s|’s)?\b", re.IGNORECASE)
PAPER_LOCATION = re.compile(
    rf"\b(?i:{_REF_WORDS.replace('|[Nn]otebooks?|Exercises?|Rows?|Scenarios?', '')})"
    rf"\.?\s*{_REF_ITEM}"
)
#: "08.1", "08b.2": exercise labels of notebooks 00-09 (leading zero), never a measured value
EXERCISE_LABEL = re.compile(r"(?<![\w.])0\d[a-z]?\.\d+(?![\w.])")
VERSION = re.compile(
    r"\b(?:glTF|GLTF|Python|python|torch|PyTorch|assimp|MathJax|Blender|OpenGL|CUDA|numpy|NumPy|"
    r"FBX|VRM|v|version)\s*\d+(?:\.\d+)+\b"
)
#: conventions of the library typed in prose everywhere: token -> the library value it states
LIBRARY_CONSTANTS: dict[str, tuple[float, str]] = {
    "30 fps": (30.0, "retarget_lib.core.ground.REFERENCE_FPS"),
}
ALLOWLIST = re.compile(r"<!--\s*constants\s*:(.*?)-->", re.IGNORECASE | re.DOTALL)

_UNITS = (
    r"mm|cm|km|m|ms|s|secs?|seconds?|mins?|minutes?|h|hrs?|hours?|deg|degrees?|fps|Hz|kHz|"
    r"KB|MB|GB|TB|KiB|MiB|GiB|kB|steps?|iterations?|iters?|epochs?|frames?|k|K|M"
)
#: the kinds of hand-typed numbers, in the order they are reported
PATTERNS = {
    "percentage": re.compile(rf"(?<![\w.]){_NUM}\s*(?:%|percent\b)"),
    "ratio": re.compile(rf"(?<![\w.]){_NUM}\s*[x×](?![\w\d])(?!\s*\d)"),
    "unit": re.compile(
        rf"(?<![\w.]){_NUM}(?:\s*[-–]\s*{_NUM})?(?:\s*|-)(?:{_UNITS})(?![\w])|(?<![\w.]){_NUM}\s*°"
    ),
    "decimal": re.compile(r"(?<![\w.])\d+\.\d+(?:e[-+]?\d+)?(?![\w.])|(?<![\w.])\d+e[-+]?\d+\b"),
}


@dataclass(frozen=True)
class Violation:
    """A hand-typed number in a notebook's Markdown source.

    Attributes:
        cell: index of the Markdown cell in the notebook.
        kind: ``"decimal"``, ``"percentage"``, ``"ratio"`` or ``"unit"``.
        token: the number as typed.
        context: the sentence around it (shortened).
    """

    cell: int
    kind: str
    token: str
    context: str

    def __str__(self) -> str:
        return f"cell {self.cell}: {self.kind} {self.token!r} in: {self.context}"


def _strip_code_and_markup(text: str) -> str:
    text = re.sub(r"```.*?```", " ", text, flags=re.DOTALL)
    text = re.sub(r"~~~.*?~~~", " ", text, flags=re.DOTALL)
    text = re.sub(r"``.+?``", " CODE ", text, flags=re.DOTALL)
    text = re.sub(r"`[^`]*`", " CODE ", text)  # inline code may wrap a line
    text = re.sub(r"<!--.*?-->", " ", text, flags=re.DOTALL)
    text = re.sub(r"\]\([^)]*\)", "]", text)  # link targets
    text = re.sub(r"https?://\S+|doi:\S+|www\.\S+", " URL ", text)
    text = re.sub(r"<[^>\n]+>", " ", text)  # HTML tags and their attributes
    return text


def _sentences(text: str) -> list[str]:
    protected = re.sub(
        r"\b(et al|e\.g|i\.e|vs|cf|approx|Eqs?|Secs?|Figs?|Apps?|Algs?|Tabs?|resp)\.",
        lambda m: m.group(0)[:-1] + "\0",
        text,
    )
    parts = re.split(
        r"\n\s*\n|\n\s*(?=[-*+]\s|\d+\.\s|#|\|)|(?<=[.!?])\s+(?=[A-Z*_(\[$\"“])", protected
    )
    sentences: list[str] = []
    for part in (p.replace("\0", ".") for p in parts if p.strip()):
        if part.lstrip().startswith("$$") and sentences:
            sentences[-1] += (
                "\n" + part
            )  # a display equation belongs to the sentence introducing it
        else:
            sentences.append(part)
    return sentences


def is_citation(sentence: str) -> bool:
    """Whether a sentence cites a paper (rule 4 of the module docstring)."""
    if PAREN_CITATION.search(sentence):
        return True
    return bool(PAPER_WORD.search(sentence) and PAPER_LOCATION.search(sentence))


def _norm(token: str) -> str:
    return re.sub(r"\s+", "", token).replace("×", "x").lower()


def scan_markdown(source: str, cell: int = 0) -> list[Violation]:
    """The hand-typed numbers in one Markdown cell's source (see the module docstring for the
    rule)."""
    allowed = {
        _norm(tok) for block in ALLOWLIST.findall(source) for tok in block.split(",") if tok.strip()
    }
    allowed |= {_norm(tok) for tok in LIBRARY_CONSTANTS}
    found: list[Violation] = []
    for sentence in _sentences(_strip_code_and_markup(source)):
        if is_citation(sentence):
            continue
        rest = EXERCISE_LABEL.sub(" REF ", VERSION.sub(" ", REFERENCE.sub(" REF ", sentence)))
        for kind, pattern in PATTERNS.items():
            for m in pattern.finditer(rest):
                token = m.group(0).strip()
                # one report per place (a ratio or unit also contains its decimal), and an allowed
                # "0.3 m" allows its "0.3"
                rest = rest[: m.start()] + " " * (m.end() - m.start()) + rest[m.end() :]
                if _norm(token) in allowed:
                    continue
                context = " ".join(sentence.split())
                found.append(
                    Violation(
                        cell, kind, token, context if len(context) < 160 else context[:157] + "..."
                    )
                )
    return found


def notebook_violations(nb) -> list[Violation]:
    """Every hand-typed number in a notebook's Markdown cells (outputs are never scanned)."""
    out: list[Violation] = []
    for i, c in enumerate(nb.cells):
        if c.cell_type == "markdown":
            out += scan_markdown(c.source, i)
    return out


# --------------------------------------------------------------------------------- closing sections
_H2 = re.compile(r"^##\s+(.+?)\s*$", re.MULTILINE)
_EXERCISE = re.compile(
    r"\*\*Exercise\s+(\d+[a-z]?\.\d+)\.?\*\*"
)  # "**Exercise 05.2**" or "**Exercise 05.2.**"


def section_problems(nb, number: str) -> list[str]:
    """What is wrong with a notebook's closing sections (empty when nothing is).

    Args:
        nb: the notebook.
        number: its number as in the file name, e.g. ``"05"`` or ``"08b"``.
    """
    problems: list[str] = []
    heads = [
        (i, m.group(1))
        for i, c in enumerate(nb.cells)
        if c.cell_type == "markdown"
        for m in _H2.finditer(c.source)
    ]
    names = [h for _, h in heads]
    where = {}
    for want in ("Summary", "Exercises", "References"):
        if want not in names:
            problems.append(f"no '## {want}' heading")
        else:
            where[want] = max(i for i, h in heads if h == want)
    if len(where) < 3:
        return problems
    if names[-3:] != ["Summary", "Exercises", "References"]:
        problems.append(
            f"the last '##' sections are {names[-3:]}, not ['Summary', 'Exercises', 'References']"
        )
    s, e, r = where["Summary"], where["Exercises"], where["References"]
    if not s < e < r:
        problems.append("Summary, Exercises and References are not in that order")
        return problems
    if not any(
        "Equations covered:" in c.source for c in nb.cells[s:e] if c.cell_type == "markdown"
    ):
        problems.append("the Summary has no 'Equations covered: ...' line")
    exercises = [
        (i, m.group(1))
        for i in range(e, r)
        if nb.cells[i].cell_type == "markdown"
        for m in _EXERCISE.finditer(nb.cells[i].source)
    ]
    if not 3 <= len(exercises) <= 5:
        problems.append(f"{len(exercises)} exercises (want 3-5, each '**Exercise {number}.k**')")
    for k, (i, label) in enumerate(exercises):
        if label.split(".")[0] != number:
            problems.append(f"Exercise {label} is not numbered {number}.k")
        end = exercises[k + 1][0] if k + 1 < len(exercises) else r
        problems += _exercise_problems(nb.cells[i + 1 : end], label)
    return problems


_CHECK = r"check_(?:function|value|prediction)\(\s*['\"]{label}['\"]"


def _exercise_problems(cells, label: str) -> list[str]:
    header = STUDENT_HEADER.format(label=label)
    student = next(
        (
            i
            for i, c in enumerate(cells)
            if c.cell_type == "code" and c.source.split("\n")[0] == header
        ),
        None,
    )
    if student is None:
        return [f"Exercise {label}: its student cell does not start with '{header}'"]
    problems = []
    check = re.compile(_CHECK.format(label=re.escape(label)))
    if not any(c.cell_type == "code" and check.search(c.source) for c in cells[student + 1 :]):
        problems.append(
            f"Exercise {label}: no check_function/check_value/check_prediction after it"
        )
    if any("solution" in c.metadata.get("tags", []) for c in cells):
        problems.append(f"Exercise {label}: a cell tagged 'solution' (answers go to solutions/)")
    return problems
