"""Strict scenes: every mistake names the file, the key, the closest valid name and the expected type."""
import typing

import pytest

from dfloop.scene import SceneError, load_scene
from dfloop.scene.elements import registry, signature
from dfloop.scene.schema import SceneFile

GOOD = "[plant]\nnum = [1.0]\nden = [1.0, 1.0, 0.0]\n[element]\ntype = 'Saturation'\nlimit = 1.0\n"


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def error(tmp_path, text) -> SceneError:
    path = write(tmp_path, text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert isinstance(info.value, ValueError)
    assert info.value.file == path and str(path) in str(info.value)
    return info.value


@pytest.mark.parametrize("text, key, message, suggestion, expected", [
    (GOOD + "[analysis]\nverfy = true\n", "analysis.verfy", "unknown key", "verify", "bool"),
    (GOOD + "[analysys]\nverify = true\n", "analysys", "unknown section", "analysis", "table"),
    (GOOD + "[analysis]\nverify = 'false'\n", "analysis.verify", "wrong type", None, "bool"),
    (GOOD.replace("limit", "limt"), "element.limt", "unknown parameter of Saturation", "limit", "float"),
    (GOOD.replace("1.0\n", "'1.0'\n"), "element.limit", "wrong type for Saturation", None, "float"),
    (GOOD.replace("'Saturation'", "'Saturaton'"), "element.type", "unknown type 'Saturaton'", "Saturation",
     "Backlash"),
    (GOOD + "[analysis]\nplots = ['nyqist']\n", "analysis.plots.0", "unknown value 'nyqist'", "nyquist",
     "'nyquist'"),
    (GOOD + "[analysis]\nomega = [2.0, 1.0]\n", "analysis.omega", "0 < lo < hi", None, None),
    (GOOD.replace("num = [1.0]", "num = ['1']"), "plant.num.0", "wrong type", None, "float"),
    (GOOD.replace("[plant]", "[plant]\ntype = 'zpk'"), "plant.num", "unknown key", None, "gain"),
    (GOOD.replace("[plant]", "[plant]\ntype = 'tff'"), "plant.type", "unknown type 'tff'", "tf", "'zpk'"),
    (GOOD + "[sweep]\nparameter = 'element.limitt'\nvalues = [1.0, 2.0]\n", "sweep.parameter",
     "no key 'limitt'", "limit", None),
    ("plant = 5.0\n" + GOOD[GOOD.index("[element]"):], "plant", "wrong type", None, "table"),
    (GOOD.replace("[element]", "[element]\nvalue = 1.0"), "element.value", "unknown parameter", None,
     "one of limit, k"),
])
def test_each_mistake_is_named(tmp_path, text, key, message, suggestion, expected):
    err = error(tmp_path, text)
    (problem,) = [p for p in err.problems if p.key == key]
    assert message in problem.message
    assert problem.suggestion == suggestion
    if expected is not None:
        assert expected in problem.expected
    assert key in str(err) and (suggestion is None or repr(suggestion) in str(err))


def test_strict_booleans_accept_only_true_and_false(tmp_path):
    assert load_scene(write(tmp_path, GOOD + "[analysis]\nverify = false\n")).verify is False
    assert load_scene(write(tmp_path, GOOD + "[analysis]\nverify = true\n")).verify is True
    for wrong in ("'true'", "1", "0"):
        error(tmp_path, GOOD + f"[analysis]\nverify = {wrong}\n")


def test_effect_parameters_are_checked_inside_the_element(tmp_path):
    text = ("[plant]\nnum = [1.0]\nden = [1.0]\n[element]\ntype = 'DynamicBacklash'\nm1 = 1.0\nm2 = 1.0\nh = 0.1\n"
            "restitution = 0.5\neffects = [{ type = 'ViscousDamping', cc = 5.0 }, { type = 'LoadSprin', k = 2.0 }]\n"
            "periods = 2.5\n")
    err = error(tmp_path, text)
    found = {p.key: p for p in err.problems}
    assert found["element.effects.0.cc"].suggestion == "c"
    assert "ViscousDamping" in found["element.effects.0.cc"].message
    assert found["element.effects.0.c"].message.startswith("missing required parameter")
    assert found["element.effects.1.type"].suggestion == "LoadSpring"
    assert found["element.periods"].expected == "int"
    assert len(err.problems) == 4


def test_every_problem_of_a_file_is_reported_at_once(tmp_path):
    text = GOOD.replace("limit", "limt") + "[analysis]\nverfy = true\nplots = ['resid']\n[scen]\nname = 'x'\n"
    err = error(tmp_path, text)
    assert {p.key for p in err.problems} == {"element.limt", "element.limit", "analysis.verfy",
                                             "analysis.plots.0", "scen"}
    assert f"{len(err.problems)} problems" in str(err)


@pytest.mark.parametrize("text, line", [
    (GOOD + "verify true\n", 7),
    ("[plant]\nnum = [1.0\n[element]\n", 3),
    ("[plant]\nnum = [1.0]\nnum = [2.0]\n", 3),
])
def test_broken_toml_names_file_and_line(tmp_path, text, line):
    err = error(tmp_path, text)
    assert "invalid TOML" in str(err) and f"line {line}," in str(err)


def test_constructor_errors_name_the_parameter(tmp_path):
    err = error(tmp_path, GOOD.replace("limit = 1.0", "limit = -1.0"))
    (problem,) = err.problems
    assert problem.key == "element.limit" and "-1.0" in problem.message


def _sections():
    for section, field in SceneFile.model_fields.items():
        annotation = field.annotation
        models = [a for a in (annotation, *typing.get_args(annotation)) if isinstance(a, type) and
                  hasattr(a, "model_fields")]
        for model in models:
            for key in model.model_fields:
                yield section, key


@pytest.mark.parametrize("section, key", list(_sections()))
def test_a_transposed_key_suggests_the_key(tmp_path, section, key):
    """Every key of every single-table section: swapping its last two letters gives that key back."""
    typo = key[:-2] + key[-1] + key[-2]
    if typo == key:
        typo = key + "x"
    required = {"sweep": "parameter = 'element.limit'\nvalues = [1.0, 2.0]\n"}.get(section, "")
    err = error(tmp_path, GOOD + f"[{section}]\n{required}{typo} = 1.0\n")
    problem = next(p for p in err.problems if p.key == f"{section}.{typo}")
    assert problem.suggestion == key


@pytest.mark.parametrize("name", [n for n in registry()])
def test_every_registered_type_misspelt_parameter_suggests_it(name):
    """Each parameter of each element and effect: a doubled last letter suggests the parameter."""
    from dfloop.scene.elements import element_problems

    for param in signature(name).parameters:
        problems = element_problems({"type": name, param + param[-1]: 1.0}, ("element",))
        (unknown,) = [p for p in problems if p.key == f"element.{param + param[-1]}"]
        assert unknown.suggestion == param and name in unknown.message


def test_exact_is_a_strict_bool_passed_to_the_solver(tmp_path, monkeypatch):
    """``[analysis] exact`` reaches predict_limit_cycles as exact=True (and is not sent when false)."""
    import dfloop.solve
    from dfloop.scene.run import predict_cycles

    error(tmp_path, GOOD + "[analysis]\nexact = 'yes'\n")
    calls = []

    def solver(G, N, *, omega=None, amplitude=None, exact=False):
        calls.append((omega, amplitude, exact))
        return []

    monkeypatch.setattr(dfloop.solve, "predict_limit_cycles", solver)
    for flag in ("true", "false"):
        scene = load_scene(write(tmp_path, GOOD + f"[analysis]\nexact = {flag}\nomega = [0.5, 5.0]\n"))
        assert scene.exact is (flag == "true")
        predict_cycles(scene)
    assert calls == [((0.5, 5.0), None, True), ((0.5, 5.0), None, False)]
