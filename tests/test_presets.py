"""Accuracy presets (issue 9): a preset fills the knobs a scene leaves out, explicit keys win,
the resolved scene records both, and the shipped scenes take their knobs from a preset.

Pure Python (no meshes, no MPI collectives).
"""

import tomllib
from pathlib import Path

import pytest

from plantgrowth.scene import Scene, load_scene, parse_scene
from plantgrowth.scene.parts import Accuracy, Time, Tissue
from plantgrowth.scene.presets import DEFAULT_PRESET, PRESETS

SCENES = Path(__file__).resolve().parents[1] / "scenes"
KNOBS = ("tissue.h", "tissue.H", "accuracy.cell_resolution", "accuracy.cell_tolerance",
         "time.dt", "time.integrator")  # fmt: skip


def knob_values(scene: Scene) -> dict[str, object]:
    """The resolved knobs of a scene by dotted key."""
    data = scene.to_dict()
    return {k: data[k.split(".")[0]][k.split(".")[1]] for k in KNOBS}


def preset_values(name: str) -> dict[str, object]:
    return {f"{s}.{k}": v for s, knobs in PRESETS[name].items() for k, v in knobs.items()}


def test_every_preset_sets_exactly_the_knobs():
    for name in PRESETS:
        assert set(preset_values(name)) == set(KNOBS), name


@pytest.mark.parametrize("name", list(PRESETS))
def test_a_preset_fills_what_the_scene_leaves_out(name):
    scene = parse_scene({"growth": {"law": "strain"}, "accuracy": {"preset": name}})
    assert scene.accuracy.preset == name
    assert knob_values(scene) == preset_values(name)


def test_the_default_preset_is_balanced_and_the_dataclass_defaults_agree():
    assert DEFAULT_PRESET == "balanced"
    scene = parse_scene({"growth": {"law": "stress"}})
    assert scene.accuracy.preset == "balanced"
    assert knob_values(scene) == preset_values("balanced")
    tissue, time, accuracy = Tissue(), Time(), Accuracy()  # built in code, not from a file
    direct = {
        "tissue.h": tissue.h,
        "tissue.H": tissue.H,
        "time.dt": time.dt,
        "time.integrator": time.integrator,
        "accuracy.cell_resolution": accuracy.cell_resolution,
        "accuracy.cell_tolerance": accuracy.cell_tolerance,
    }
    assert direct == preset_values("balanced")


def test_explicit_keys_override_the_preset():
    data = {
        "growth": {"law": "stress"},
        "tissue": {"h": 0.3},
        "time": {"dt": 2.0},
        "accuracy": {"preset": "fine", "cell_tolerance": 0.0},
    }
    scene = parse_scene(data)
    expected = preset_values("fine") | {"tissue.h": 0.3, "time.dt": 2.0,
                                        "accuracy.cell_tolerance": 0.0,
                                        "tissue.H": 0.3}  # fmt: skip
    # fine's H is below the given h: the preset's H is raised to it (h <= H)
    assert PRESETS["fine"]["tissue"]["H"] < 0.3
    assert knob_values(scene) == expected


def test_the_resolved_scene_names_the_preset_and_every_value(tmp_path):
    scene = parse_scene({"growth": {"law": "stress"}, "accuracy": {"preset": "draft"}})
    text = scene.to_toml()
    data = tomllib.loads(text)
    assert data["accuracy"]["preset"] == "draft"
    assert data["tissue"]["h"] == PRESETS["draft"]["tissue"]["h"]
    assert data["accuracy"]["cell_tolerance"] == PRESETS["draft"]["accuracy"]["cell_tolerance"]
    (tmp_path / "scene.toml").write_text(text)
    assert load_scene(tmp_path / "scene.toml") == scene


def test_preset_mesh_sizes_are_clipped_to_a_small_tissue_but_given_ones_are_not():
    small = {"growth": {"law": "stress"}, "tissue": {"width": 0.8, "height": 0.3}}
    scene = parse_scene(small | {"accuracy": {"preset": "draft"}})
    assert PRESETS["draft"]["tissue"]["h"] > 0.15 and PRESETS["draft"]["tissue"]["H"] > 0.8
    assert scene.tissue.h == 0.15  # min(width, height) / 2
    assert scene.tissue.H == 0.8  # max(width, height)
    with pytest.raises(ValueError, match=r"tissue\.h = 0\.2 is out of range"):
        parse_scene(small | {"tissue": {"width": 0.8, "height": 0.3, "h": 0.2}})


def test_shipped_scenes_take_their_knobs_from_a_preset():
    """Reference and gradient scenes name the preset and set no knob of their own; hard cases
    keep only their time stepping (the adaptive integrator), documented in the scene."""
    for path in sorted(SCENES.glob("*.toml")) + sorted(SCENES.glob("hard/*.toml")):
        data = tomllib.loads(path.read_text())
        assert data["accuracy"]["preset"] == "balanced", path.name
        given = {f"{s}.{k}" for s in ("tissue", "accuracy", "time") for k in data.get(s, {})}
        own = given & set(KNOBS)
        assert own <= ({"time.dt", "time.integrator"} if path.parent.name == "hard" else set())
        assert knob_values(load_scene(path)) == preset_values("balanced") | {
            k: knob_values(load_scene(path))[k] for k in own
        }
