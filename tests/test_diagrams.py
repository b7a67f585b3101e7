"""Schematic diagrams (retarget_lib.viz.diagrams): every figure builds, is readable by the module's
own checks (text >= 9 pt, inside its box and the canvas, no overlapping text), and draws the numbers
of the real models (receptive fields, score counts) and real library functions."""

import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text

from retarget_lib import viz
from retarget_lib.methods.registry import method_names
from retarget_lib.models import build_model
from retarget_lib.viz import diagrams

pytestmark = pytest.mark.tooling  # nothing here depends on the thread count (make unit-threads)


def _texts(fig):
    return [t.get_text() for t in fig.findobj(Text)]


@pytest.mark.parametrize(
    "config",
    [
        None,
        {"row": "ours", "profile": "paper"},
        {"row": "A5", "profile": "fast"},
        {"row": "A1", "profile": "fast"},
    ],
)
def test_tdcn_diagram_draws_the_models_receptive_field(config):
    fig = viz.tdcn_generator_diagram(config)
    gen = build_model(config or {"row": "ours", "profile": "fast"}).generator
    assert fig.receptive_field == gen.receptive_field
    assert any(f"receptive field: {gen.receptive_field} frames" in t for t in _texts(fig))
    assert any(f"C = {gen.body.channels}" in t for t in _texts(fig))
    assert diagrams.layout_problems(fig) == []


def test_dilation_offsets_cover_the_receptive_field_without_gaps():
    levels = diagrams.dilation_offsets([(3, 1), (3, 3), (1, 1), (3, 9), (3, 27)])
    assert levels[-1].tolist() == [0]
    assert levels[0].tolist() == list(
        range(-40, 41)
    )  # 1 + 2(1 + 3 + 9 + 27) = 81 frames, every one seen
    causal = diagrams.dilation_offsets([(3, 1), (3, 3), (3, 9), (3, 27)], causal=True)
    assert causal[0].tolist() == list(range(-80, 1))


def test_patch_discriminator_diagram_counts_scores_like_the_model():
    fig = viz.patch_discriminator_diagram(clip_frames=120)
    disc = build_model({"row": "ours", "profile": "fast"}).discriminator
    assert fig.receptive_field == disc.receptive_field
    assert fig.scores == (
        120 - disc.receptive_field + 1,
        1,
    )  # valid convolutions; one logit per clip
    assert any(f"{fig.scores[0]} scores" in t for t in _texts(fig))
    assert diagrams.layout_problems(fig) == []


@pytest.mark.parametrize("draw", [viz.nkn_diagram, viz.georet_diagram, viz.eso_loop_diagram])
def test_network_diagrams_are_readable(draw):
    fig = draw()
    assert isinstance(fig, Figure)
    width, height = fig.get_size_inches()
    assert width <= 9.01 and height <= 4.6
    assert diagrams.layout_problems(fig) == []


def test_eso_diagram_reads_the_iterations_from_the_config():
    fig = viz.eso_loop_diagram({"iterations": 7, "lr": 0.5, "reach": 0.2})
    assert fig.iterations == 7
    assert any("N = 7" in t for t in _texts(fig)) and any("20 cm" in t for t in _texts(fig))


def test_dataflow_covers_every_registered_method_with_real_functions():
    assert set(diagrams.DATAFLOW_METHODS) == set(method_names())
    for method in diagrams.DATAFLOW_METHODS:
        fig = viz.method_dataflow_diagram(method)
        assert diagrams.layout_problems(fig) == [], method
        for stage in fig.stages:
            assert callable(diagrams.resolve_stage(stage)), stage
            assert stage.short in _texts(fig)
        assert (
            fig.stages[0].function == "io.bvh.load_bvh"
            and fig.stages[-1].function == "io.bvh.save_bvh"
        )
    with pytest.raises(ValueError):
        viz.method_dataflow_diagram("magic")


def test_layout_problems_finds_small_and_overlapping_text():
    fig = Figure(figsize=(2, 1))
    fig.text(0.5, 0.5, "tiny", fontsize=6)
    fig.text(0.5, 0.5, "tiny too", fontsize=10)
    problems = diagrams.layout_problems(fig)
    assert any("< 9" in p for p in problems) and any("overlaps" in p for p in problems)
