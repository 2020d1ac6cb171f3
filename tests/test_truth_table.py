"""The solver table of :func:`prbdm.truth.bending_frequencies`: each model takes the options its
entry lists (each checked by its check) and refuses every other, and the mode limit is the
entry's. Refusals come before any solve, so these run in milliseconds."""
import pytest

from prbdm.errors import BadInput
from prbdm.geometry import Beam
from prbdm.truth import MAX_MODES, MODELS, SOLVERS, bending_frequencies

UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.1, 0.1], thickness=0.02)
# a bad value for each checked option, and the message that names it
BAD = {"selection": ("nope", "selection: must be one of"),
       "degree": (5, "degree: must be one of 2, 3, 4"),
       "shear_factor": (1.5, r"shear_factor: must be a number in \(0, 1\]")}


def test_the_public_model_names_and_limits_are_the_table():
    assert MODELS == ("analytic", "beam", "plate", "mindlin") == tuple(SOLVERS)
    assert MAX_MODES == {"analytic": 200, "beam": 100, "plate": 30, "mindlin": 30}


@pytest.mark.parametrize("model", MODELS)
def test_an_option_outside_the_table_is_refused_with_its_name(model):
    with pytest.raises(BadInput, match=rf"model '{model}'.*(unknown option 'colour'|no options)"):
        bending_frequencies(UNIFORM, model, 2, colour=1)


@pytest.mark.parametrize("model", MODELS)
def test_one_mode_past_the_limit_is_refused(model):
    top = SOLVERS[model].max_modes
    with pytest.raises(BadInput, match=rf"\[1, {top}\] for model '{model}'"):
        bending_frequencies(UNIFORM, model, top + 1)


@pytest.mark.parametrize("model, option", [(m, o) for m in MODELS for o in BAD
                                           if SOLVERS[m].options.get(o) is not None])
def test_each_checked_option_refuses_a_bad_value(model, option):
    value, message = BAD[option]
    with pytest.raises(BadInput, match=message):
        bending_frequencies(UNIFORM, model, 2, **{option: value})


def test_the_checked_options_are_those_listed_above():
    checked = {o for s in SOLVERS.values() for o, check in s.options.items() if check}
    assert checked == set(BAD)
