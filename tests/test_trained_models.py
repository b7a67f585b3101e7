"""The shipped default checkpoints retarget: identity on the source's own skeleton, and better than
copying rotations on the Table 4 test pairs (issue: "models must work, not only run")."""

import numpy as np
import pytest

from retarget_lib.evaluation.identity import identity_clips, identity_errors
from retarget_lib.evaluation.tdcn import cmu_cases, evaluate_method, tdcn_cases
from retarget_lib.methods.registry import get_method

pytestmark = [
    pytest.mark.data,
    pytest.mark.slow,
]  # shipped checkpoints, the synthetic set, the CMU clips


@pytest.fixture(scope="module")
def tdcn():
    return get_method("tdcn").retargeter()


def test_default_tdcn_returns_a_clip_on_its_own_skeleton(tdcn):
    errors = identity_errors(tdcn)
    by_group = errors.groupby("group")["mean"].mean()
    assert set(by_group.index) == {"synthetic", "mannequin-x", "cmu"}
    # the bar we promise users: at most 2 cm mean root-relative joint error for a 1.7 m body on each
    # set (the residual network is exact here by construction; 2 cm is the contract, not the
    # expectation)
    assert (by_group <= 2.0).all(), by_group.to_dict()
    assert (errors["root"] <= 2.0).all()


def test_default_tdcn_beats_copy_on_table4_pairs(tdcn):
    cases = tdcn_cases()[::6]  # 16 of the 96 pairs, every scenario
    ours = evaluate_method(tdcn, cases)
    copy = evaluate_method(get_method("copy").retargeter(), cases)
    for length in ("short", "long"):
        assert ours[length].mean() < copy[length].mean(), (
            length,
            ours[length].mean(),
            copy[length].mean(),
        )
    # and on most pairs, not only on average
    assert np.mean(ours["short"].values <= copy["short"].values) >= 0.75


def test_default_tdcn_beats_copy_on_the_real_cmu_clips(tdcn):
    # real skeletons never trained on, whose rest poses differ from every training character's
    # (01_01/01_03 stand with splayed legs): the network must compensate the rest pose, as the
    # ground-truth convention does. Every clip (averaged over the five test characters: on one whose
    # rest pose matches a clip's, copy is already exact), not only on average.
    cases = cmu_cases()
    ours = evaluate_method(tdcn, cases).groupby("clip")["long"].mean()
    copy = evaluate_method(get_method("copy").retargeter(), cases).groupby("clip")["long"].mean()
    assert (ours <= 0.5 * copy).all(), (ours.to_dict(), copy.to_dict())


@pytest.fixture(scope="module")
def contact_network():
    from retarget_lib.methods.contact import load_contact_model, retarget_with_network

    model, _ = load_contact_model(get_method("contact").default_checkpoint())
    return lambda motion, character: retarget_with_network(model, motion, character)


def test_default_contact_network_returns_a_clip_on_its_own_character(contact_network):
    errors = identity_errors(contact_network, characters=True)
    by_group = errors.groupby("group")[["mean", "hands"]].mean()
    assert set(by_group.index) == {"synthetic", "mannequin-x"}
    # Looser than TDCN's 2 cm: the network alone is trained to move limbs out of its own body
    # (Eint) and hands onto their contacts (Ej2j), so on its own character it does not return the
    # input exactly (measured 2.2-2.3 cm at 1.7 m for the shipped checkpoint, hands 2.9-3.5 cm).
    # 3 cm / 5 cm keep that honest; the 7.8 % of the height (13 cm) this issue started from fails.
    assert (by_group["mean"] <= 3.0).all(), by_group.to_dict()
    assert (by_group["hands"] <= 5.0).all(), by_group.to_dict()


IDENTITY_FRAMES = 45


def test_default_contact_method_with_eso_returns_a_clip_on_its_own_character():
    # `--method contact` (network + ESO, the source's own mesh for its hand contacts): the 2 cm
    # contract of TDCN. ESO's weak term also removes the network's root drift.
    contact = get_method("contact").retargeter()
    clips = [c for c in identity_clips() if c.character is not None][
        ::4
    ]  # walk, clap, wave; two bodies
    # the first IDENTITY_FRAMES frames of each: ESO costs ~0.4 s per frame on 2 cores, and the
    # identity contract holds frame by frame (the whole clips took 6 min of the suite)
    clips = [c._replace(motion=c.motion.slice(0, IDENTITY_FRAMES)) for c in clips]
    errors = identity_errors(lambda m, c: contact(m, c, source_character=c), clips, characters=True)
    assert (errors["mean"] <= 2.0).all(), errors.to_dict()
    assert (errors["root"] <= 10.0).all(), errors.to_dict()


def test_default_contact_network_beats_copy_on_the_contact_cases(contact_network):
    from retarget_lib.evaluation.contact import (
        contact_cases,
        evaluate_contact_methods,
    )
    from retarget_lib.evaluation.contact.methods import _skeleton_method

    cases = contact_cases("fast")[
        ::5
    ]  # 8 of the 36 cases, skinny and bulky targets, several families
    methods = {
        "network": lambda case, eint: contact_network(case.source, case.target),
        "copy": _skeleton_method(get_method("copy").retargeter()),
    }
    means = (
        evaluate_contact_methods(methods, cases, eval_every=6)
        .groupby("method")
        .mean(numeric_only=True)
    )
    net, copy = means.loc["network"], means.loc["copy"]
    assert net["global position MSE"] <= copy["global position MSE"], means
    assert net["vertex contact MSE"] < copy["vertex contact MSE"], means
    assert net["interpenetration"] <= 0.2 * copy["interpenetration"], means
