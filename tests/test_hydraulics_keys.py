"""``[hydraulics]`` scene keys (docs/model.md, water fluxes; plantgrowth/scene/hydraulics.py):
what a valid table gives, the round trip, and one named error per kind of mistake.

Pure Python (no meshes, no MPI collectives): every rank runs the same checks.
"""

import tomllib

import pytest

from plantgrowth.scene import SceneError, parse_scene
from plantgrowth.scene.fields import ExprField, Field
from plantgrowth.scene.hydraulics import Potential

BASE = """model = "micro"
[growth]
law = "stress"
[micro]
nx = 4
[regions]
strand = {expr = "x1 < 1"}
"""
GOOD = (
    BASE
    + """[hydraulics]
osmotic = 0.002
conductivity = {from = 1, to = 2}
initial_potential = -0.0001
[[hydraulics.supply]]
edge = "left"
conductance = 2.0
potential = {times = [0, 30], values = [0, -0.0005]}
[[hydraulics.supply]]
region = "strand"
conductance = 0.5
"""
)


def parse(text: str):
    return parse_scene(tomllib.loads(text))


def test_a_valid_table_gives_the_hydraulics_and_the_turgor_input():
    scene = parse(GOOD)
    h = scene.hydraulics
    assert h.osmotic == Field(0.002, 0.002, scene.tissue.width, scene.tissue.height)
    assert scene.P1 is h.osmotic  # Pi is the scene's turgor input
    assert h.conductivity.start == 1.0 and h.conductivity.end == 2.0
    assert h.initial_potential == -0.0001
    left, strand = h.supplies
    assert (left.kind, left.name, left.conductance) == ("edge", "left", 2.0)
    assert (strand.kind, strand.name, strand.conductance) == ("region", "strand", 0.5)
    assert strand.potential(17.0) == 0.0  # default psi_s = 0
    assert "pressure.P1" not in scene.parameter_fields()
    assert set(scene.hydraulics.fields()) <= set(scene.parameter_fields())


def test_round_trip_and_no_hydraulics_is_none():
    scene = parse(GOOD)
    assert parse(scene.to_toml()) == scene
    assert parse(BASE).hydraulics is None
    assert "hydraulics" not in parse(BASE).to_dict()


def test_potential_in_time_step_and_linear():
    step = Potential((0.0, 30.0), (0.0, -1.0), "step")
    linear = Potential((10.0, 30.0), (0.0, -1.0), "linear")
    assert [step(t) for t in (0.0, 29.999, 30.0, 99.0)] == [0.0, 0.0, -1.0, -1.0]
    assert [linear(t) for t in (0.0, 10.0, 20.0, 30.0, 40.0)] == [0.0, 0.0, -0.5, -1.0, -1.0]


def test_osmotic_may_be_an_expression_checked_at_the_cells():
    scene = parse(BASE + '[hydraulics]\nconductivity = 1\nosmotic = {expr = "0.001 * x1"}\n')
    assert isinstance(scene.hydraulics.osmotic, ExprField)
    assert parse(BASE + "[hydraulics]\nconductivity = 1\n").hydraulics.osmotic(0, 0) == 0.001


BAD = [  # (the [hydraulics] table and supplies, fragments of the error)
    ("osmotic = 0.001\n", ("hydraulics.conductivity is required",)),
    ("conductivity = -1\n", ("hydraulics.conductivity = -1", "[0, 1e+12]")),
    ("conductivity = {from = 1, to = -1}\n", ("hydraulics.conductivity.to",)),
    ("conductivity = 1\nosmotic = nan\n", ("hydraulics.osmotic", "finite")),
    ("conductivity = 1\nosmotic = -0.1\n", ("hydraulics.osmotic = -0.1",)),
    ("conductivity = 1\nosmotic = 'high'\n", ("hydraulics.osmotic",)),
    ("conductivity = 1\ninitial_potential = inf\n", ("hydraulics.initial_potential",)),
    ("conductivity = 1\npressure = 1\n", ("unknown key 'hydraulics.pressure'",)),
    ("conductivity = 1\nsupply = 1\n", ("hydraulics.supply: expected an array",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'bottom'\nconductance = 1\n",
     ("hydraulics.supply[0].edge = 'bottom'", "symmetry plane")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'Left'\nconductance = 1\n",
     ("hydraulics.supply[0].edge = 'Left'", "'left', 'right', 'top'")),
    ("conductivity = 1\n[[hydraulics.supply]]\nregion = 'disc'\nconductance = 1\n",
     ("hydraulics.supply[0].region = 'disc'", "'strand'")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nregion = 'strand'\n"
     "conductance = 1\n", ("hydraulics.supply[0]", "not both")),
    ("conductivity = 1\n[[hydraulics.supply]]\nconductance = 1\n",
     ("hydraulics.supply[0]", "none was given")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\n",
     ("hydraulics.supply[0].conductance is required",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 0\n",
     ("hydraulics.supply[0].conductance = 0", "(0, 1e+12]")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\nflux = 2\n",
     ("unknown key 'hydraulics.supply[0].flux'",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "[[hydraulics.supply]]\nedge = 'top'\nconductance = 2\n",
     ("hydraulics.supply[1].edge = 'top' is supplied twice",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "potential = {times = [0, 1]}\n", ("hydraulics.supply[0].potential.values is required",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "potential = {times = [0, 1], values = [1]}\n", ("hydraulics.supply[0].potential:",
                                                        "one value per time")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "potential = {times = [2, 1], values = [0, 1]}\n",
     ("hydraulics.supply[0].potential.times[1] = 1.0", "increase strictly")),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "potential = {times = [0, 1], values = [0, 1], interpolation = 'cubic'}\n",
     ("hydraulics.supply[0].potential.interpolation = 'cubic'",)),
    ("conductivity = 1\n[[hydraulics.supply]]\nedge = 'top'\nconductance = 1\n"
     "potential = {times = [-1], values = [0]}\n",
     ("hydraulics.supply[0].potential.times[0] = -1",)),
]  # fmt: skip


@pytest.mark.parametrize("table, fragments", BAD, ids=[f[0][:40] for _, f in BAD])
def test_bad_hydraulics_is_a_named_error(table, fragments):
    with pytest.raises(SceneError) as e:
        parse(BASE + "[hydraulics]\n" + table)
    for fragment in fragments:
        assert fragment in str(e.value)


@pytest.mark.parametrize(
    "change, fragments",
    [
        ("[pressure]\nP1 = 0.001\n", ("pressure.P1: not with [hydraulics]",)),
    ],
)
def test_hydraulics_with_what_cannot_take_it_is_refused(change, fragments):
    top = not change.startswith("[")  # a top-level key comes before the tables
    hydraulic = BASE + "[hydraulics]\nconductivity = 1\n"
    text = change + hydraulic if top else hydraulic + change
    with pytest.raises(SceneError) as e:
        parse(text)
    for fragment in fragments:
        assert fragment in str(e.value)


@pytest.mark.parametrize("kinematics", ["linear", "finite"])
@pytest.mark.parametrize("model", ["macro", "micro", "both"])
def test_every_model_takes_a_hydraulic_scene_in_either_kinematics(model, kinematics):
    scene = parse(f'model = "{model}"\nkinematics = "{kinematics}"\n[growth]\nlaw = "stress"\n'
                  "[hydraulics]\nconductivity = 1\n")  # fmt: skip
    assert scene.hydraulics is not None
    assert (scene.model, scene.kinematics) == (model, kinematics)


@pytest.mark.parametrize("integrator", ["exp", "euler", "adaptive"])
def test_every_integrator_takes_a_hydraulic_scene(integrator):
    """The adaptive integrator's sub-steps advance the water too (issue 35: it was refused)."""
    scene = parse(BASE + f'[time]\nintegrator = "{integrator}"\n[hydraulics]\nconductivity = 1\n')
    assert scene.hydraulics is not None and scene.time.integrator == integrator


@pytest.mark.parametrize(
    "model, water, fragment",
    [("macro", False, "no [hydraulics]"), ("micro", True, "cells.csv")],
)
def test_water_fields_need_the_macro_model_with_hydraulics(model, water, fragment):
    text = f'model = "{model}"\n[growth]\nlaw = "stress"\n[output]\nfields = ["u", "psi"]\n'
    text += "[hydraulics]\nconductivity = 1\n" if water else ""
    with pytest.raises(SceneError, match=r"output.fields: \['psi'\]") as e:
        parse(text)
    assert fragment in str(e.value)
