"""Scene files: loading, defaults, fields, round trip and one test per class of mistake.

Pure Python (no meshes, no MPI collectives): every rank runs the same checks on its own tmp_path.
"""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from plantgrowth.base.errors import InputError
from plantgrowth.scene import Scene, SceneError, load_scene, parse_scene
from plantgrowth.scene.fields import Field
from plantgrowth.scene.limits import DEFAULT_OUTPUT
from plantgrowth.scene.parts import Material, Time
from plantgrowth.scene.presets import PRESETS

SCENES = Path(__file__).resolve().parents[1] / "scenes"
LAW = '[growth]\nlaw = "stress"\n'
# docs/model.md section 9 intervals: param -> (keys, strain interval, stress interval)
GRADIENTS = {
    "E": (["material.E"], (0.5, 2.0), (0.5, 2.0)),
    "nu": (["material.nu"], (0.0, 0.45), (0.0, 0.45)),
    "P1": (["pressure.P1"], (0.0005, 0.002), (0.0005, 0.002)),
    "tau": (["growth.tau"], (0.0, 0.01), (0.0, 0.005)),
    "eta": (["growth.eta"], (0.5, 2.0), (0.5, 2.0)),
    "w": (["cell.w"], (0.025, 0.1), (0.025, 0.1)),
    "l": (["cell.l1", "cell.l2"], (0.5, 2.0), (0.5, 2.0)),
}


def parse(text: str) -> Scene:
    """Parse a TOML snippet; a [growth] table with law = "stress" is added if missing."""
    return parse_scene(tomllib.loads(text if "[growth]" in text else text + LAW))


def test_shipped_scenes_exist_and_load():
    names = {p.name for p in SCENES.glob("*.toml")}
    expected = {f"reference_{law}.toml" for law in ("stress", "strain")}
    expected |= {f"gradient_{p}_{law}.toml" for p in GRADIENTS for law in ("stress", "strain")}
    assert expected <= names
    for name in sorted(expected):
        assert (SCENES / name).read_text().startswith("#"), f"{name} lacks a header comment"
        scene = load_scene(SCENES / name)
        assert scene.growth.law in name
        assert scene.time.integrator == "exp" and scene.time.n_steps == 60


@pytest.mark.parametrize("law", ["stress", "strain"])
def test_reference_scene_is_model_section_9(law):
    scene = load_scene(SCENES / f"reference_{law}.toml")
    assert scene == parse_scene({"growth": {"law": law}})  # the defaults are the reference
    assert all(f.is_constant for f in scene.parameter_fields().values())


@pytest.mark.parametrize("law", ["stress", "strain"])
@pytest.mark.parametrize("param", list(GRADIENTS))
def test_gradient_scenes_vary_one_parameter(param, law):
    scene = load_scene(SCENES / f"gradient_{param}_{law}.toml")
    keys, strain_interval, stress_interval = GRADIENTS[param]
    interval = strain_interval if law == "strain" else stress_interval
    reference = parse_scene({"growth": {"law": law}}).parameter_fields()
    for key, f in scene.parameter_fields().items():
        if key in keys:
            assert (f.start, f.end) == interval
        else:
            assert f == reference[key], key


def test_defaults():
    scene = parse(LAW)
    assert scene.model == "macro"
    t = scene.tissue
    assert (t.width, t.height) == (4 * math.sqrt(3), 3.0)
    assert (t.h, t.H) == (PRESETS["balanced"]["tissue"]["h"], PRESETS["balanced"]["tissue"]["H"])
    assert t.width == 6.928203230275509
    values = {k: f.start for k, f in scene.parameter_fields().items()}
    assert values == {
        "cell.l1": 1.0,
        "cell.l2": 1.0,
        "cell.theta": 30.0,
        "cell.w": 0.05,
        "material.E": 1.0,
        "material.nu": 0.3,
        "pressure.P1": 0.001,
        "growth.eta": 1.0,
        "growth.tau": 0.0,
    }
    g = scene.growth
    assert (g.law, g.clamp, g.Fg0) == ("stress", 1.0, ((1.0, 0.0), (0.0, 1.0)))
    assert (scene.time.t_max, scene.time.dt, scene.time.integrator) == (60.0, 1.0, "exp")
    assert scene.time.n_steps == 60
    assert scene.loads == {}
    assert scene.output.fields == DEFAULT_OUTPUT == ("u", "Fg", "G", "sigma_hom", "E_hom")
    assert (scene.accuracy.cell_resolution, scene.accuracy.key_tolerance) == (2, 1e-6)
    assert scene.micro_nx == 16


def test_field_evaluation():
    constant = Field(2.0, 2.0, 4.0, 2.0)
    x1, x2 = np.linspace(0.0, 4.0, 5), np.linspace(0.0, 2.0, 5)
    assert constant.is_constant and np.all(constant.gradient(x1, x2) == 0.0)
    np.testing.assert_array_equal(constant(np.array([0.0, 1.0, 4.0]), 0.0), [2.0, 2.0, 2.0])
    assert constant.to_toml() == 2.0
    linear = Field(1.0, 3.0, 4.0, 2.0)
    assert not linear.is_constant and linear.slope == 0.5
    np.testing.assert_array_equal(linear.gradient(x1, x2), np.tile([0.5, 0.0], (5, 1)))
    np.testing.assert_allclose(linear(x1, x2), 1.0 + 0.5 * x1, rtol=0, atol=1e-15)
    assert linear(x1, x2).shape == (5,)
    assert linear(np.zeros((2, 3)), 0.0).shape == (2, 3)
    assert linear.to_toml() == {"from": 1.0, "to": 3.0}
    vertical = Field(1.0, 3.0, 4.0, 2.0, along="x2")  # from x2 = 0 to x2 = height
    np.testing.assert_allclose(vertical(x1, x2), 1.0 + x2, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(vertical.gradient(x1, x2), np.tile([0.0, 1.0], (5, 1)))
    assert vertical.to_toml() == {"from": 1.0, "to": 3.0, "along": "x2"}


def test_linear_field_from_toml():
    scene = parse("[material]\nE = {from = 0.5, to = 2}\n")
    E = scene.material.E
    assert (E.start, E.end, E.width) == (0.5, 2.0, scene.tissue.width)
    assert E(np.array([scene.tissue.width]), 0.0)[0] == pytest.approx(2.0, rel=1e-15)


def test_integers_accepted_and_loads_normalised():
    scene = parse(
        "[time]\nt_max = 6\ndt = 2\n[loads]\nleft = [-1, 0]\nright = [1, 0]\ntop = [0, 0]\n"
    )
    assert (scene.time.t_max, scene.time.n_steps) == (6.0, 3)
    assert scene.loads == {"left": (-1.0, 0.0), "right": (1.0, 0.0)}  # the zero "top" is dropped
    assert isinstance(scene.loads["right"][0], float)


def test_time_steps_tolerate_round_off():
    assert parse("[time]\nt_max = 0.3\ndt = 0.1\n").time.n_steps == 3  # 0.3/0.1 = 2.9999...


@pytest.mark.parametrize("model", ["macro", "micro", "both"])
def test_models_and_eps_hom_under_any_law(model):
    for law in ("stress", "strain", "none"):
        text = f'model = "{model}"\n[growth]\nlaw = "{law}"\n[output]\nfields = ["u", "eps_hom"]\n'
        scene = parse(text)
        assert scene.model == model and scene.output.fields == ("u", "eps_hom")


ROUND_TRIP = """
model = "macro"
[tissue]
width = 5
height = 2.5
h = 0.125
H = 0.5
[cell]
l1 = {from = 0.5, to = 2.0}
l2 = {from = 0.5, to = 2.0}
theta = 25.0
w = 0.03
[material]
E = {from = 0.5, to = 2}
nu = -0.2
[pressure]
P1 = {from = 0.0005, to = 0.002}
[growth]
law = "strain"
eta = 0.7
tau = {from = 0, to = 0.01}
clamp = 0.25
Fg0 = [[1.1, 0.1], [0.0, 0.9]]
[time]
t_max = 0.9
dt = 0.1
integrator = "euler"
[loads]
left = [-0.001, 0]
right = [0.001, 0]
top = [0, 2e-3]
[output]
fields = ["eps_hom", "u"]
[accuracy]
cell_resolution = 3
key_tolerance = 1e-4
[micro]
nx = 8
resolution = 3
"""


@pytest.mark.parametrize("name", ["custom", "reference_stress", "gradient_w_strain"])
def test_round_trip(name, tmp_path):
    scene = parse(ROUND_TRIP) if name == "custom" else load_scene(SCENES / f"{name}.toml")
    text = scene.to_toml()
    again = parse_scene(tomllib.loads(text))
    assert again == scene
    assert again.to_toml() == text
    path = tmp_path / "resolved.toml"
    path.write_text(text)
    assert load_scene(path) == scene


# (TOML snippet, regex the message must match at its start)
MISTAKES = {
    "unknown top-level key": ("foo = 1\n", r"unknown key 'foo' \(valid keys: model, tissue"),
    "unknown nested key": (
        '[growth]\nlaw = "stress"\netta = 2\n',
        r"unknown key 'growth\.etta' \(valid keys: law, eta, tau, clamp, Fg0\)",
    ),
    "unknown key in a field": (
        "[material]\nE = {from = 1, too = 2}\n",
        r"unknown key 'material\.E\.too'",
    ),
    "field missing an end": ("[material]\nE = {from = 1}\n", r"material\.E: "),
    "string for number": ("[time]\ndt = 'one'\n", r"time\.dt: expected a number, got 'one'"),
    "bool for number": ("[material]\nE = true\n", r"material\.E: expected a number"),
    "bool for tissue number": ("[tissue]\nh = false\n", r"tissue\.h: expected a number"),
    "list for number": ("[cell]\nw = [0.05]\n", r"cell\.w: expected a number"),
    "number for table": ("tissue = 3\n", r"tissue: expected a table"),
    "list for table": ("micro = [16]\n", r"micro: expected a table"),
    "number for string": ("model = 1\n", r"model: expected a string"),
    "bad model": ("model = 'mezzo'\n", r"model = 'mezzo' is invalid"),
    "bad integrator": ("[time]\nintegrator = 'rk4'\n", r"time\.integrator = 'rk4'"),
    "bad preset": ("[accuracy]\npreset = 'fast'\n", r"accuracy\.preset = 'fast' is invalid"),
    "number for preset": ("[accuracy]\npreset = 1\n", r"accuracy\.preset: expected a string"),
    "string for list": ("[output]\nfields = 'u'\n", r"output\.fields: expected an array"),
    "unknown output": ("[output]\nfields = ['u', 'stress']\n", r"output\.fields\[1\] = 'stress'"),
    "duplicate output": ("[output]\nfields = ['u', 'u']\n", r"output\.fields = "),
    "float for integer": ("[accuracy]\ncell_resolution = 2.0\n", r"accuracy\.cell_resolution: "),
    "resolution zero": ("[accuracy]\ncell_resolution = 0\n", r"accuracy\.cell_resolution = 0"),
    "tolerance too big": ("[accuracy]\nkey_tolerance = 0.1\n", r"accuracy\.key_tolerance = 0\.1"),
    "odd nx": ("[micro]\nnx = 15\n", r"micro\.nx = 15"),
    "nx zero": ("[micro]\nnx = 0\n", r"micro\.nx = 0"),
    "nan": ("[material]\nnu = nan\n", r"material\.nu = nan is out of range"),
    "inf": ("[time]\nt_max = inf\n", r"time\.t_max = inf is out of range"),
    "inf at a field end": ("[material]\nE = {from = 1, to = inf}\n", r"material\.E\.to = inf"),
    "zero width": ("[tissue]\nwidth = 0\n", r"tissue\.width = 0 is out of range"),
    "negative height": ("[tissue]\nheight = -1\n", r"tissue\.height = -1"),
    "zero h": ("[tissue]\nh = 0\n", r"tissue\.h = 0 is out of range"),
    "h above half the height": ("[tissue]\nh = 2\n", r"tissue\.h = 2 is out of range"),
    "H below h": ("[tissue]\nH = 0.05\n", r"tissue\.H = 0\.05 is out of range"),
    "H above the tissue": ("[tissue]\nH = 8\n", r"tissue\.H = 8 is out of range"),
    "zero l1": ("[cell]\nl1 = 0\n", r"cell\.l1 = 0(\.0)? is out of range"),
    "negative w": ("[cell]\nw = -0.1\n", r"cell\.w = -0\.1 is out of range"),
    "zero E": ("[material]\nE = 0\n", r"material\.E = 0(\.0)? is out of range"),
    "negative P1": ("[pressure]\nP1 = -0.001\n", r"pressure\.P1 = -0\.001"),
    "negative eta": ('[growth]\nlaw = "strain"\neta = -1\n', r"growth\.eta = -1"),
    "negative tau at one end": (
        '[growth]\nlaw = "strain"\ntau = {from = 0, to = -1}\n',
        r"growth\.tau\.to = -1",
    ),
    "zero clamp": ('[growth]\nlaw = "strain"\nclamp = 0\n', r"growth\.clamp = 0"),
    "zero dt": ("[time]\ndt = 0\n", r"time\.dt = 0 is out of range"),
    "nu = 0.5": ("[material]\nnu = 0.5\n", r"material\.nu = 0\.5 is out of range"),
    "nu > 0.5 at one end": ("[material]\nnu = {from = 0, to = 0.6}\n", r"material\.nu\.to = 0\.6"),
    "nu = -1": ("[material]\nnu = -1\n", r"material\.nu = -1(\.0)? is out of range"),
    "w too large": ("[cell]\nw = 0.9\n", r"cell\.w = 0\.9 leaves the cell no void"),
    "w too large at one end": (
        "[cell]\nw = {from = 0.05, to = 0.9}\n",
        r"cell\.w = 0\.9.*\(at x1 = 6\.9",
    ),
    "w too large for small cells": (
        "[cell]\nl1 = 0.2\nl2 = 0.2\nw = 0.2\n",
        r"cell\.w = 0\.2 leaves",
    ),
    "theta = 90": ("[cell]\ntheta = 90\n", r"cell\.theta = 90(\.0)? is out of range"),
    "theta = 0": ("[cell]\ntheta = 0\n", r"cell\.theta = 0(\.0)? is out of range"),
    "theta negative at one end": (
        "[cell]\ntheta = {from = -10, to = 30}\n",
        r"cell\.theta\.from = -10",
    ),
    "t_max < dt": ("[time]\nt_max = 0.5\ndt = 1\n", r"time\.t_max = 0\.5 is smaller than time\.dt"),
    "t_max/dt not whole": (
        "[time]\nt_max = 10.5\n",
        r"time\.t_max = 10\.5 is not a whole number.*dt",
    ),
    "missing law": ("[growth]\neta = 1.0\n", r"growth\.law is required"),
    "bad law": ("[growth]\nlaw = 'stres'\n", r"growth\.law = 'stres' is invalid"),
    "law of wrong type": ("[growth]\nlaw = 1\n", r"growth\.law: expected a string"),
    "load on bottom": (
        "[loads]\nbottom = [0, 1]\n",
        r"loads\.bottom: the bottom edge x2 = 0 is the symmetry",
    ),
    "unknown edge": ("[loads]\nfront = [0, 1]\n", r"unknown key 'loads\.front'"),
    "load of 3 numbers": ("[loads]\nright = [0, 1, 2]\n", r"loads\.right: expected an array of 2"),
    "load not a number": ("[loads]\ntop = [0, 'x']\n", r"loads\.top\[1\]: expected a number"),
    "Fg0 det < 0": ("[growth]\nlaw = 'stress'\nFg0 = [[1, 0], [0, -1]]\n", r"growth\.Fg0 = .*det"),
    "Fg0 det = 0": ("[growth]\nlaw = 'stress'\nFg0 = [[1, 2], [0.5, 1]]\n", r"growth\.Fg0 = .*det"),
    "Fg0 not 2x2": (
        "[growth]\nlaw = 'stress'\nFg0 = [[1, 0, 0], [0, 1, 0]]\n",
        r"growth\.Fg0\[0\]",
    ),
    "Fg0 string entry": (
        "[growth]\nlaw = 'stress'\nFg0 = [[1, 0], [0, '1']]\n",
        r"growth\.Fg0\[1\]\[1\]",
    ),
    "Fg0 nan entry": (
        "[growth]\nlaw = 'stress'\nFg0 = [[1, 0], [0, nan]]\n",
        r"growth\.Fg0\[1\]\[1\]",
    ),
    "huge width": ("[tissue]\nwidth = 1e300\n", r"tissue\.width = 1e\+300 is out of range"),
    "huge height": ("[tissue]\nheight = 2e6\n", r"tissue\.height = "),
    "h too small for the mesh limit": ("[tissue]\nh = 1e-3\n", r"tissue\.h = 0\.001 is too small"),
    "too many steps": ("[time]\nt_max = 1\ndt = 1e-300\n", r"time\.t_max / time\.dt = .* too many"),
    "huge t_max": ("[time]\nt_max = 1e300\n", r"time\.t_max = 1e\+300 is out of range"),
    "huge E": ("[material]\nE = 1e300\n", r"material\.E = 1e\+300 is out of range"),
    "huge integer E": (
        "[material]\nE = 1" + "0" * 400 + "\n",
        r"material\.E = 1000.* far too large",
    ),
    "huge P1": ("[pressure]\nP1 = 1e300\n", r"pressure\.P1 = 1e\+300"),
    "huge clamp": ("[growth]\nlaw = 'stress'\nclamp = 1e300\n", r"growth\.clamp = 1e\+300"),
    "huge Fg0": (
        "[growth]\nlaw = 'stress'\nFg0 = [[1e300, 0], [0, 1]]\n",
        r"growth\.Fg0\[0\]\[0\]",
    ),
    "huge load": ("[loads]\nright = [1e300, 0]\n", r"loads\.right\[0\] = 1e\+300"),
    "huge cell": ("[cell]\nl1 = 1e300\n", r"cell\.l1 = 1e\+300"),
    "huge resolution": ("[accuracy]\ncell_resolution = 1000000\n", r"accuracy\.cell_resolution = "),
    "huge nx": ("[micro]\nnx = 1000000\n", r"micro\.nx = 1000000"),
}


@pytest.mark.parametrize("text, pattern", MISTAKES.values(), ids=MISTAKES.keys())
def test_mistake_names_the_key(text, pattern):
    with pytest.raises(SceneError, match="^" + pattern):
        parse(text)


def test_no_growth_table_means_missing_law():
    with pytest.raises(SceneError, match=r"^growth\.law is required"):
        parse_scene({})


def test_scene_error_is_an_input_error():
    assert issubclass(SceneError, InputError) and issubclass(SceneError, ValueError)


def test_dataclasses_validate_on_construction():
    width = 4.0
    with pytest.raises(SceneError, match=r"^material\.nu = 0\.5"):
        Material(Field(1.0, 1.0, width, 1.0), Field(0.5, 0.5, width, 1.0))
    with pytest.raises(SceneError, match=r"^time\.t_max = 10\.5"):
        Time(t_max=10.5, dt=1.0)
    scene = parse(LAW)
    fields = {k.split(".")[1]: f for k, f in scene.parameter_fields().items() if k[:4] == "cell"}
    with pytest.raises(SceneError, match=r"^cell\.l1: field width"):
        Scene(
            scene.model,
            type(scene.tissue)(width=5.0),
            type(scene.cell)(**fields),
            scene.material,
            Field(0.001, 0.001, 5.0, scene.tissue.height),
            scene.growth,
            scene.time,
        )


def _file_error(path, pattern):
    with pytest.raises(SceneError, match=pattern) as info:
        load_scene(path)
    assert str(info.value).startswith(str(path))


def test_file_errors(tmp_path):
    _file_error(tmp_path / "missing.toml", "not found")
    _file_error(tmp_path, "is a directory")
    for name, content, pattern in [
        ("empty.toml", b"", "is empty"),
        ("blank.toml", b"  \n\n", "is empty"),
        ("garbage.toml", bytes(range(256)) * 4, "not a text file"),
        ("latin1.toml", '[growth]\nlaw = "stress"  # \xe9\n'.encode("latin-1"), "not UTF-8"),
        ("invalid.toml", b'[growth\nlaw = "stress"\n', "invalid TOML"),
        ("duplicate.toml", b'[growth]\nlaw = "stress"\nlaw = "strain"\n', "invalid TOML"),
    ]:
        path = tmp_path / name
        path.write_bytes(content)
        _file_error(path, pattern)


def test_errors_in_a_file_name_the_key_and_the_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[growth]\nlaw = "stress"\n[material]\nnu = 0.5\n')
    with pytest.raises(SceneError, match=r"^material\.nu = 0\.5 is out of range") as info:
        load_scene(path)
    assert str(info.value).endswith(f"(in {path})")
    path.write_text('[growth]\nlaw = "stress"\n')
    assert load_scene(str(path)) == load_scene(path)  # str or PathLike


@pytest.mark.parametrize("model", ["micro", "both"])
@pytest.mark.parametrize(
    "extra, key",
    [
        ("[cell]\nw = {from = 0.03, to = 0.06}", "cell.w"),
        ("[cell]\nl1 = {from = 1, to = 2}", "cell.l1"),
        ("[loads]\nright = [0.001, 0.0]", "loads"),
    ],
)
def test_micro_rejects_geometric_fields_and_loads(model, extra, key):
    """docs/model.md section 7: geometric fields are not defined for the cellular tissue; it has no
    edges to load."""
    with pytest.raises(SceneError, match=key):
        parse(f'model = "{model}"\n[growth]\nlaw = "stress"\n{extra}')
