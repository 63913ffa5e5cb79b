"""Scene errors in the project's words: no validator-library phrasing reaches the user, for every kind of
constraint the schema has (list lengths, bounds), and a parameter name a newcomer guesses points to the real one."""
from __future__ import annotations

import pytest

from dfloop.scene.errors import SceneError, validator_message
from dfloop.scene.load import load_scene

PLANT = '[plant]\nnum = [5.0]\nden = [1.0, 1.0, 0.0]\n'
ELEMENT = '[element]\ntype = "Backlash"\nh = 1.0\n'
SWEEP = '[sweep]\nparameter = "plant.num.0"\nvalues = {{ start = 1.0, stop = 2.0, num = {num} }}\n'
VALIDATOR_PHRASES = ("should", "after validation", "Input ", "input should", "pydantic")

CASES = [  # (scene text, key, words the message must hold)
    (PLANT + ELEMENT + "[analysis]\nomega = [1.0]\n", "analysis.omega", "needs at least 2 values, got 1 value: [1.0]"),
    (PLANT + ELEMENT + "[analysis]\nomega = [1.0, 2.0, 3.0]\n", "analysis.omega",
     "takes at most 2 values, got 3 values: [1.0, 2.0, 3.0]"),
    ('[plant]\nnum = [5.0]\nden = []\n' + ELEMENT, "plant.den", "needs at least 1 value, got 0 values: []"),
    (PLANT + "delay = -1.0\n" + ELEMENT, "plant.delay", "must be >= 0.0, got -1.0"),
    (PLANT + ELEMENT + "[analysis]\nverify_perturbation = 2.0\n", "analysis.verify_perturbation",
     "must be <= 0.95, got 2.0"),
    (PLANT + ELEMENT + "[analysis]\nverify_perturbation = 0.0\n", "analysis.verify_perturbation",
     "must be >= 0.001, got 0.0"),
    (PLANT + ELEMENT + SWEEP.format(num=1), "sweep.values.num", "must be >= 2, got 1"),
    (PLANT + '[element]\ntype = "Saturation"\nlimit = 1.0\nslope = 2.0\n', "element.slope", "did you mean 'k'?"),
    (PLANT + '[element]\ntype = "Backlash"\nclearance = 1.0\n', "element.clearance", "did you mean 'h'?"),
]


@pytest.mark.parametrize("text, key, words", CASES, ids=[c[1] + ":" + c[2][:20] for c in CASES])
def test_scene_errors_use_the_projects_words(tmp_path, text, key, words):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    message = str(err.value)
    assert f"{key}: " in message and words in message, message
    for phrase in VALIDATOR_PHRASES:
        assert phrase not in message, message


def test_unknown_validator_kind_still_names_the_value():
    assert validator_message("some_new_kind", {}, 3.5) == "invalid value 3.5"
    assert validator_message("greater_than", {"gt": 0}, -2) == "must be > 0, got -2"


def test_element_keyword_guesses_name_the_real_parameter():
    import dfloop as df
    from dfloop.describing.base import DescribingFunction
    from dfloop.errors import DfloopError

    with pytest.raises(TypeError, match=r"Saturation has no parameter 'slope' \(did you mean 'k'\?\); its "
                                        r"parameters are limit, k"):
        df.Saturation(limit=1.0, slope=2.0)
    with pytest.raises(DfloopError, match=r"'clearance' \(did you mean 'h'\?\)"):
        df.Backlash(clearance=1.0)
    with pytest.raises(TypeError, match=r"'dead_band' \(did you mean 'dead_zone'\?\)"):
        df.Relay(M=1.0, dead_band=0.1)   # a relay's band is dead_zone, a dead zone's is delta
    assert df.Saturation(limit=1.0, k=2.0).k == 2.0

    class Custom(DescribingFunction):   # a user's element taking any keyword: its own TypeError is kept
        def __init__(self, **options):
            raise TypeError("Custom needs a gain")

        def _evaluate(self, A, omega):
            return A

    with pytest.raises(TypeError, match="^Custom needs a gain$"):
        Custom(slope=1.0)
