"""Scene files: parsing, the generic type mechanism, and clear errors for bad scenes."""
import numpy as np
import pytest

from dfloop.scene import build, load_scene


def write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def test_plant_with_delay_is_a_delayed_system(tmp_path):
    scene = load_scene(write(tmp_path, """
[plant]
num = [1.0]
den = [1.0, 1.0]
delay = 0.5
[element]
type = "Saturation"
limit = 1.0
"""))
    w = np.array([0.3, 2.0])
    expected = np.exp(-0.5j * w) / (1j * w + 1)
    assert scene.plant.delay == 0.5  # a DelayedSystem: evaluated at s like a python-control system
    assert np.allclose(scene.plant(1j * w), expected, rtol=1e-14)


def test_controller_multiplies_plant(tmp_path):
    scene = load_scene(write(tmp_path, """
[controller]
num = [2.0, 1.0]
den = [1.0]
[plant]
num = [1.0]
den = [1.0, 1.0, 0.0]
[element]
type = "Saturation"
limit = 1.0
"""))
    s = 0.7j
    assert np.isclose(complex(scene.plant(s)), (2 * s + 1) / (s * s + s), rtol=1e-13)


@pytest.mark.parametrize(
    "text, match",
    [
        ("[element]\ntype='Saturation'\nlimit=1.0\n", "plant"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\n[element]\ntype='Nope'\n", "unknown type 'Nope'"),
        ("[plant]\ntype='foo'\n[element]\ntype='Saturation'\nlimit=1.0\n", "plant.type"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\ndelay=-1.0\n[element]\ntype='Saturation'\nlimit=1.0\n", "plant.delay"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\n[element]\ntype='Saturation'\nlimit=-1.0\n", "limit"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\n[element]\ntype='Saturation'\nlimit=1.0\n[analysis]\nomega=[1.0]\n",
         "analysis.omega"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\n[element]\ntype='Saturation'\nlimit=1.0\n[analysis]\nplots=['x']\n",
         "analysis.plots"),
        ("[plant]\nnum=[1.0]\nden=[1.0,1.0]\n[element]\ntype='MassBacklash'\nm1=1.0\nm2=1.0\nh=0.1\n"
         "[analysis]\nverify=true\n", "analysis.verify: MassBacklash has no time-domain operator"),
    ],
)
def test_bad_scene_names_the_problem(tmp_path, text, match):
    with pytest.raises(ValueError, match=match):
        load_scene(write(tmp_path, text))


def test_missing_file_raises(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_scene(tmp_path / "absent.toml")


def test_build_rejects_bad_parameters():
    with pytest.raises(ValueError, match="Saturation"):
        build({"type": "Saturation", "nonsense": 1.0})
