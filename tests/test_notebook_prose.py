"""No hand-typed result numbers in the notebooks' Markdown, and every notebook closes with Summary,
Exercises (3-5, each a student cell `# exercise N.k: your code here` and a check after it) and
References.

The rule (what counts as a hand-typed number, what is allowed) is documented in
`retarget_lib/notebook/prose_lint.py`. A measured value belongs in a code cell's
`prose(f"...{value:.2f}...")` output, which is computed and therefore never scanned here.
"""

import re
from pathlib import Path

import nbformat
import pytest

from retarget_lib.notebook.prose_lint import notebook_violations, scan_markdown, section_problems

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("[0-9][0-9]*_*.ipynb"))


def kinds(text):
    return [(v.kind, v.token) for v in scan_markdown(text)]


# ---------------------------------------------------------------------------------------- the rule
@pytest.mark.parametrize(
    "text, expected",
    [
        ("Copy's error is 0.58 m on average.", [("unit", "0.58 m")]),
        ("The gap is a steady 10% between the curves.", [("percentage", "10%")]),
        ("Ours is 3x better, and 649× worse elsewhere.", [("ratio", "3x"), ("ratio", "649×")]),
        ("It trains in 7 min on two cores.", [("unit", "7 min")]),
        ("The hands end 45 cm apart.", [("unit", "45 cm")]),
        ("Its benefit shows (1.65 -> 0.06).", [("decimal", "1.65"), ("decimal", "0.06")]),
        ("An 81-frame window sees every frame.", [("unit", "81-frame")]),
        ("The residual is 2.6e-4 relative.", [("decimal", "2.6e-4")]),
        ("A weight of 0.5 and 10.2 as well.", [("decimal", "0.5"), ("decimal", "10.2")]),
    ],
)
def test_hand_typed_numbers_are_found(text, expected):
    assert kinds(text) == expected


@pytest.mark.parametrize(
    "text",
    [
        "Eq. 8 and Eqs. 4-8 define it; see Sec. 3.4, Table 4, Fig. 3, Appendix F and notebook 04.",
        "**Exercise 05.2** Compute the height of `ada`.",
        "Convert your 08.1 number, then check 08b.2.",  # exercise labels (leading zero)
        "Kim et al. 2020 and Villegas et al. (ICCV 2021) use 22 joints and 16 characters.",
        "The twist loss uses α = 100° (Sec. 4.2).",  # parenthesised paper location
        "The paper's Table 4 reports 0.58 for copy.",  # 'paper' + a location
        "Set `train.steps=3000` or `lambda_h = 10` in the config.",  # config constants in backticks
        "Try `f(x,\n gamma_foot=10.0)` there.",  # inline code wrapping a line
        "<!-- constants: 100k, 0.5 -->\nThe paper-form schedule trains 100k steps at a rate of "
        "0.5.",
        # a display equation of a cited sentence
        "Its objective (Eq. 6) is\n\n$$L = L_c + 0.1 L_r$$",
        "Download from [arXiv](https://arxiv.org/abs/2109.07431), doi "
        "https://doi.org/10.1111/cgf.13947.",
        "Every GLB passes the glTF 2.0 validator (Python 3.11, assimp 5.2.5).",
        "```\nretarget train --profile fast train.steps=0.5\n```",
        "A 3 × 3 matrix and 4x4 transforms.",
    ],
)
def test_allowed_numbers_are_not_flagged(text):
    assert kinds(text) == []


def test_allowlist_is_per_cell_and_exact():
    assert kinds("<!-- constants: 15 cm -->\nThe reach rule is 15 cm, the margin 3 cm.") == [
        ("unit", "3 cm")
    ]
    assert kinds("The reach rule is 15 cm.") == [("unit", "15 cm")]


def test_table_in_parentheses_alone_is_not_a_citation():
    """'(Table 4)' names our tables too: a measured number next to it is still flagged."""
    assert kinds("Copy scores 0.58 (Table 4).") == [("decimal", "0.58")]


def test_outputs_are_not_scanned():
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell("prose(f'{err:.2f} m')")
    cell.outputs = [
        nbformat.v4.new_output("display_data", data={"text/markdown": "Error **0.58 m**"})
    ]
    nb.cells = [nbformat.v4.new_markdown_cell("No numbers here."), cell]
    assert notebook_violations(nb) == []


def _closing(
    n_exercises=3, header="# exercise {label}.{k}: your code here", check="check_value", label="05"
):
    """Closing sections: each exercise a student cell, then a check cell."""
    md, code = nbformat.v4.new_markdown_cell, nbformat.v4.new_code_cell
    cells = [
        md("## Summary\n- key idea\n\nEquations covered: Kim et al. Eqs. 4-8"),
        md("## Exercises"),
    ]
    for k in range(1, n_exercises + 1):
        cells += [
            md(f"**Exercise {label}.{k}** Do it."),
            code(header.format(label=label, k=k) + "\nx = NotAnswered"),
            code(f'{check}("{label}.{k}", x, solution_value("{label}.{k}", "x", globals()))'),
        ]
    cells.append(md("## References\n- Kim et al. 2020"))
    nb = nbformat.v4.new_notebook()
    nb.cells = cells
    return nb


def test_closing_sections_rule():
    assert section_problems(_closing(), "05") == []
    assert section_problems(_closing(check="check_function"), "05") == []
    assert any("2 exercises" in p for p in section_problems(_closing(2), "05"))
    assert any("not numbered 05.k" in p for p in section_problems(_closing(label="06"), "05"))
    assert any(
        "does not start with" in p
        for p in section_problems(_closing(header="# exercise 05.{k}: write here"), "05")
    )
    assert any("no check_function" in p for p in section_problems(_closing(check="print"), "05"))
    moved = _closing()
    moved.cells = moved.cells[-1:] + moved.cells[:-1]
    assert section_problems(moved, "05")
    nb = _closing()
    nb.cells[3].metadata["tags"] = ["solution"]
    assert any("tagged 'solution'" in p for p in section_problems(nb, "05"))


# ------------------------------------------------------------------------------------ the notebooks
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_no_hand_typed_numbers_in_markdown(path):
    found = notebook_violations(nbformat.read(path, as_version=4))
    assert not found, (
        f"{path.name}: {len(found)} hand-typed numbers in Markdown (render them with "
        "prose(f'...'), cite the paper, or list paper constants in "
        "<!-- constants: ... -->):\n" + "\n".join(map(str, found))
    )


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_summary_exercises_references(path):
    problems = section_problems(nbformat.read(path, as_version=4), path.name.split("_", 1)[0])
    assert not problems, f"{path.name}: " + "; ".join(problems)


def test_library_constants_typed_in_prose_match_the_library():
    import importlib

    from retarget_lib.notebook.prose_lint import LIBRARY_CONSTANTS

    for token, (value, where) in LIBRARY_CONSTANTS.items():
        module, name = where.rsplit(".", 1)
        assert getattr(importlib.import_module(module), name) == value, (token, where)
        assert str(int(value)) in token


def test_the_tdcn_authors_are_cited_as_the_paper_names_them():
    """SangBin Kim, Inbum Park, Seongsu Kwon and JungHyun Han (the paper and its official
    repository); an earlier text had "Kim, Park, Lee" everywhere."""
    root = Path(__file__).resolve().parents[1]
    texts = [
        root / "README.md",
        *root.glob("docs/*.md"),
        *root.glob("configs/*.yaml"),
        *NOTEBOOKS,
        *root.glob("retarget_lib/**/*.py"),
    ]
    wrong = [
        p.relative_to(root).as_posix()
        for p in texts
        if "Park, Lee" in p.read_text(encoding="utf-8")
    ]
    assert not wrong, wrong
    assert "Kim, Park, Kwon, Han" in (root / "README.md").read_text(encoding="utf-8")


#: the longest Markdown cell a student reads in one go (words; comments and table rows, which are
#: looked up rather than read through, left out)
MARKDOWN_WORDS = 200


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_no_wall_of_text(path):
    long = []
    for i, cell in enumerate(nbformat.read(path, as_version=4).cells):
        if cell.cell_type == "markdown":
            prose = "\n".join(
                line
                for line in re.sub(r"<!--.*?-->", "", cell.source, flags=re.S).splitlines()
                if not line.lstrip().startswith("|")
            )
            n = len(re.findall(r"[A-Za-z0-9]+", prose))
            if n > MARKDOWN_WORDS:
                long.append((i, n))
    assert not long, (
        f"{path.name}: Markdown cells over {MARKDOWN_WORDS} words (cell, words): {long}"
    )


#: the longest Markdown a notebook may show in one cell, written or generated (issue: "walls of
#: generated prose"); a longer cell is two ideas, or a table retold in words
MAX_MARKDOWN_CHARS = 1200


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_no_markdown_cell_or_generated_paragraph_is_a_wall(path):
    nb = nbformat.read(path, as_version=4)
    long = []
    for i, cell in enumerate(nb.cells):
        texts = [cell.source] if cell.cell_type == "markdown" else []
        texts += [
            o.get("data", {}).get("text/markdown", "")
            for o in cell.get("outputs", [])
            if cell.cell_type == "code"
        ]
        long += [(i, len(t)) for t in texts if len(t) > MAX_MARKDOWN_CHARS]
    assert not long, f"{path.name}: (cell, characters) over {MAX_MARKDOWN_CHARS}: {long}"


#: the notebooks whose study needs a knob (a slider over precomputed pictures, `viz.knob`), and
#: what it moves: 02 the dilations, 03 a loss constant, 05 a joint's rotation under LBS, 05b the
#: contact margin, 06 the cone's sigma, 07b ESO's reach, 09 the ablation row
KNOB_NOTEBOOKS = ("02", "03", "05", "05b", "06", "07b", "09")


@pytest.mark.parametrize("number", KNOB_NOTEBOOKS)
def test_the_study_notebooks_have_a_knob(number):
    (path,) = [p for p in NOTEBOOKS if p.name.split("_", 1)[0] == number]
    nb = nbformat.read(path, as_version=4)
    assert any(
        c.cell_type == "code" and re.search(r"^viz\.knob\(", c.source, re.M) for c in nb.cells
    ), f"{path.name}: no viz.knob(...) cell"
