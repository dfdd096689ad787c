"""Parameter fields along x2 and as expressions (issue 11, item 1; plantgrowth/scene/expression.py,
scene/fields.py, scene/places.py).

Parser: precedence, associativity, functions, named errors with positions, no eval. Fields:
symbolic gradients against finite differences, TOML round trip. Validation at the places used
(coarse nodes, fine cells, micro cell centres). Runs: an expression equal to a linear field gives
the same run to round-off; an x2 gradient acts in the expected direction; mpirun -n 2 gives
the serial run. Small runs: h = 0.5, H = 2, one P2 element across a cell wall, 2 steps.
"""

from __future__ import annotations

import csv
import shutil
import subprocess
import tomllib

import h5py
import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.runner.output import step_file
from plantgrowth.runner.scene_run import check_used_values
from plantgrowth.scene import SceneError, parse_scene
from plantgrowth.scene.expression import ExpressionError, parse_expression
from plantgrowth.scene.fields import ExprField, Field
from plantgrowth.scene.limits import REFERENCE_WIDTH
from plantgrowth.scene.toml_text import dict_to_toml

XY = ("x1", "x2")


def value(text: str, x1=0.0, x2=0.0) -> float:
    return float(parse_expression("k", text, XY)(x1=x1, x2=x2))


# --- the parser --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        ("1 + 2 * 3", 7.0),
        ("(1 + 2) * 3", 9.0),
        ("2 ** 3 ** 2", 512.0),  # right-associative
        ("-2 ** 2", -4.0),  # unary minus binds looser than ** (as in Python)
        ("2 ** -1", 0.5),
        ("--3", 3.0),
        ("8 / 4 / 2", 1.0),  # left-associative
        ("1 - 2 - 3", -4.0),
        ("1e-3 * 1E3 + .5", 1.5),
        ("where(2 > 1, 10, 20) + where(1 >= 2, 1, 2)", 12.0),
        ("(1 < 2) + (2 <= 2) + (3 == 3) + (3 != 3)", 3.0),  # comparisons give 0 or 1
        ("min(3, 1, 2) + max(1, 5)", 6.0),
        ("abs(-2) + sqrt(4) + exp(0) + log(1) + tanh(0) + cos(0) + sin(0)", 6.0),
        ("cos(pi)", -1.0),
    ],
)
def test_parser_precedence_and_functions(text, expected):
    assert value(text) == pytest.approx(expected, rel=1e-15)


def test_expressions_are_vectorised_over_points():
    x1, x2 = np.array([0.0, 2.0, 4.0]), np.array([1.0, 1.0, 3.0])
    e = parse_expression("k", "where(x1 > 3, 0.6, 0.3) + x2 ** 2", XY)
    np.testing.assert_array_equal(e(x1=x1, x2=x2), [1.3, 1.3, 9.6])
    assert parse_expression("k", "2", XY)(x1=x1, x2=x2).shape == (3,)  # a constant broadcasts


@pytest.mark.parametrize(
    "text, message",
    [
        ("x1 + y", "material.E.expr: unknown name 'y' at position 5 in 'x1 + y'"),
        ("__import__('os')", "unknown name '__import__' at position 0"),  # no eval
        ("x1.real", "unexpected character '.' at position 2"),  # no attribute access
        ("[x1][0]", "unexpected character '[' at position 0"),
        ("lambda: 1", "unknown name 'lambda' at position 0"),
        ("x1 +", "expected a number, a name or '(', found the end at position 4"),
        ("(x1", "expected ')', found the end at position 3"),
        ("x1)", "unexpected ')' at position 2"),
        ("2x1", "unexpected 'x1' at position 1"),
        ("sin(x1, x2)", "sin takes 1 argument(s), got 2 at position 0"),
        ("where(x1, 1)", "where takes 3 argument(s), got 2 at position 0"),
        ("max(x1)", "max takes at least 2 argument(s), got 1 at position 0"),
        ("exp", "function 'exp' needs its arguments in parentheses at position 3"),
        ("1 < x1 < 2", "chained comparison (use where or parentheses) at position 7"),
        ("x1 = 1", "unexpected character '=' at position 3"),
        ("", "material.E.expr: the expression is empty"),
        ("(" * 60 + "1" + ")" * 60, "nesting deeper than 50 at position 50"),
        ("-" * 60 + "1", "nesting deeper than 50 at position 49"),
        ("1+" * 600 + "1", "material.E.expr: 1201 characters, more than 1000"),
    ],
)
def test_parser_errors_name_the_key_and_the_position(text, message):
    with pytest.raises(ExpressionError) as caught:
        parse_expression("material.E.expr", text, XY)
    assert message in str(caught.value)
    assert str(caught.value).startswith("material.E.expr: ")


def test_expression_error_is_an_input_error_and_not_a_string_is_named():
    with pytest.raises(ExpressionError, match=r"^loads\.right\[0\]\.expr: expected a string"):
        parse_expression("loads.right[0].expr", 3.0, ("s",))
    with pytest.raises(ExpressionError, match="unknown name 'x1'"):  # loads know s only
        parse_expression("loads.right[0].expr", "x1", ("s",))
    assert issubclass(ExpressionError, ValueError)


# --- fields and their gradients ----------------------------------------------------------------

NONLINEAR = [
    "x1 ** 2 * x2",
    "exp(-x1 / 3) * sin(x2) / (1 + x2)",
    "sqrt(1 + x1) + log(2 + x2) - tanh(x1 - x2) + cos(x1 * x2)",
    "abs(x1 - 2.5) + min(x1, x2, 1.5) + max(x2, 0.5 * x1)",
    "where(x1 > 2, x2 ** 3, 2 * x1) + (1 + x1) ** (0.5 + x2 / 4)",
]


@pytest.mark.parametrize("text", NONLINEAR)
def test_symbolic_gradient_matches_finite_differences(text):
    """Central differences, step 1e-6: truncation ~1e-12 and round-off ~1e-10 relative, hence
    the tolerance 1e-7 (points kept away from the kinks of abs, min, max and where)."""
    f = ExprField(parse_expression("k", text, XY))
    rng = np.random.default_rng(1)
    x1, x2 = rng.uniform(0.1, 4.0, 40), rng.uniform(0.1, 3.0, 40)
    smooth = (np.abs(x1 - 2.5) > 1e-3) & (np.abs(x1 - x2) > 1e-3) & (np.abs(x1 - 2) > 1e-3)
    smooth &= (np.abs(x2 - 1.5) > 1e-3) & (np.abs(x2 - 0.5 * x1) > 1e-3)
    x1, x2, d = x1[smooth], x2[smooth], 1e-6
    numeric = np.stack([(f(x1 + d, x2) - f(x1 - d, x2)) / (2 * d),
                        (f(x1, x2 + d) - f(x1, x2 - d)) / (2 * d)], axis=-1)  # fmt: skip
    np.testing.assert_allclose(f.gradient(x1, x2), numeric, rtol=1e-7, atol=1e-7)


def test_a_linear_expression_equals_the_linear_field_to_round_off():
    width, height = REFERENCE_WIDTH, 3.0
    linear = Field(0.5, 2.0, width, height)
    expr = ExprField(parse_expression("k", f"0.5 + (2.0 - 0.5) * x1 / {width!r}", XY))
    vertical = Field(0.5, 2.0, width, height, along="x2")
    expr_x2 = ExprField(parse_expression("k", "0.5 + 1.5 * x2 / 3", XY))
    x1, x2 = np.meshgrid(np.linspace(0, width, 9), np.linspace(0, height, 7))
    for a, b in ((linear, expr), (vertical, expr_x2)):
        np.testing.assert_allclose(b(x1, x2), a(x1, x2), rtol=4e-16, atol=0)  # a few ulp
        np.testing.assert_allclose(b.gradient(x1, x2), a.gradient(x1, x2), rtol=4e-16, atol=0)


def scene(tables: dict) -> object:
    return parse_scene({"growth": {"law": "stress"}} | tables)


def test_fields_round_trip_through_the_resolved_toml():
    s = scene(
        {
            "material": {"E": {"expr": "1 + 0.1 * x2 ** 2"}, "nu": {"from": 0.2, "to": 0.3,
                         "along": "x2"}},
            "pressure": {"P1": {"expr": "where(x1 < 3, 0.001, 0.002)"}},
            "growth": {"law": "strain", "eta": {"from": 1, "to": 2, "along": "x1"}},
        }
    )  # fmt: skip
    assert s.material.E.to_toml() == {"expr": "1 + 0.1 * x2 ** 2"}
    assert s.material.nu.to_toml() == {"from": 0.2, "to": 0.3, "along": "x2"}
    assert s.growth.eta.to_toml() == {"from": 1.0, "to": 2.0}  # along x1 is the default
    assert parse_scene(tomllib.loads(s.to_toml())) == s
    assert s.dotted()["material.E"] == {"expr": "1 + 0.1 * x2 ** 2"}


def test_a_constant_expression_is_a_constant_field_checked_at_once():
    s = scene({"cell": {"w": {"expr": "0.1 / 2"}}})
    assert s.cell.w.is_constant and s.cell.at(1.0, 2.0).w == 0.05
    with pytest.raises(SceneError, match=r"^material\.nu = 0\.6 is out of range.*\(-1, 0\.5\)"):
        scene({"material": {"nu": {"expr": "0.3 * 2"}}})


@pytest.mark.parametrize(
    "tables, message",
    [
        ({"material": {"E": {"expr": "1", "from": 1}}}, r"material\.E: an expression field is"),
        ({"material": {"E": {"from": 1, "along": "x2"}}}, r"material\.E: a linear field needs"),
        ({"material": {"E": {"from": 1, "to": 2, "along": "y"}}}, r"material\.E\.along = 'y'"),
        ({"material": {"E": {"expr": "E + 1"}}}, r"material\.E\.expr: unknown name 'E' at"),
        ({"material": {"E": {"expr": 2}}}, r"material\.E\.expr: expected a string"),
        ({"material": {"E": {"exp": "1"}}}, r"unknown key 'material\.E\.exp'.*'expr'"),
        ({"material": {"E": "1 + x1"}}, r"material\.E: expected a number, \{from"),
        ({"material": {"E": {"from": 1, "to": -1, "along": "x2"}}}, r"material\.E\.to = -1"),
    ],
)
def test_bad_field_tables_are_named(tables, message):
    with pytest.raises(SceneError, match="^" + message):
        scene(tables)


def test_micro_needs_a_constant_geometry_also_along_x2():
    with pytest.raises(SceneError, match=r"^cell\.w is a field, but model = 'micro'"):
        scene({"model": "micro", "cell": {"w": {"from": 0.05, "to": 0.06, "along": "x2"}}})


def test_x2_linear_geometry_is_checked_at_its_ends():
    with pytest.raises(SceneError, match=r"^cell\.w = .* \(at x1 = 0, x2 = 3\)"):
        scene({"cell": {"w": {"from": 0.05, "to": 0.9, "along": "x2"}}})


# --- validation at the places used (collective: also under mpirun) -----------------------------

SMALL = {"tissue": {"h": 0.5, "H": 2.0}, "accuracy": {"cell_resolution": 1}}


@pytest.mark.mpi
def test_a_bad_value_in_the_interior_is_found_and_named():
    """nu = 0.6 for x1 > 3 (the ends are fine): the first coarse node past x1 = 3 (grid
    step 6.93/3 = 2.31: node 2 at x1 = 4.62) is named, with the range."""
    s = scene(SMALL | {"material": {"nu": {"expr": "where(x1 > 3, 0.6, 0.3)"}}})
    with pytest.raises(SceneError) as caught:
        check_used_values(s, MPI.COMM_WORLD)
    assert str(caught.value) == (
        "material.nu = 0.6 at x1 = 4.6188, x2 = 0 (coarse node 2) is out of range: it must be "
        "finite and in (-1, 0.5)"
    )


@pytest.mark.mpi
def test_a_bad_value_between_the_coarse_nodes_is_found_on_the_fine_cells():
    """eta < 0 on 0.5 < x1 < 1.5 only: no coarse node there (x1 = 0, 2.31, ...), but fine
    cells; the one with the smallest (x1, x2) is named, the same on every rank."""
    s = scene(
        SMALL | {"growth": {"law": "stress", "eta": {"expr": "where(abs(x1 - 1) < 0.5, -1, 1)"}}}
    )
    with pytest.raises(SceneError) as caught:
        check_used_values(s, MPI.COMM_WORLD)
    text = str(caught.value)
    assert text.startswith("growth.eta = -1.0 at x1 = 0.") and "(fine cell midpoint)" in text
    assert text.endswith("is out of range: it must be finite and in [0, 1e+12]")
    assert len(set(MPI.COMM_WORLD.allgather(text))) == 1


@pytest.mark.mpi
def test_nan_and_infinite_values_are_named():
    s = scene(SMALL | {"pressure": {"P1": {"expr": "0.001 * log(x1 - 1)"}}})
    with pytest.raises(
        SceneError, match=r"^pressure\.P1 = nan at x1 = 0, x2 = 0 \(coarse node 0\)"
    ):
        check_used_values(s, MPI.COMM_WORLD)
    s = scene(SMALL | {"material": {"E": {"expr": "1 / abs(x2 - 1.5)"}}})
    with pytest.raises(
        SceneError, match=r"^material\.E = inf at x1 = 0, x2 = 1\.5 \(coarse node 4\)"
    ):
        check_used_values(s, MPI.COMM_WORLD)


@pytest.mark.mpi
def test_the_cell_geometry_is_checked_at_the_coarse_nodes():
    s = scene(SMALL | {"cell": {"w": {"expr": "where(x1 > 3, 0.9, 0.05)"}}})
    with pytest.raises(SceneError, match=r"^cell\.w = 0\.9 .*\(at x1 = 4\.6188, x2 = 0 \(coarse "):
        check_used_values(s, MPI.COMM_WORLD)


@pytest.mark.mpi
def test_micro_fields_are_checked_at_the_cell_centres():
    """Nx = 4: two rows of cells, centres at x2 = 0 and 1.5; P1 < 0 for x2 > 1 hits the top
    row only."""
    s = scene({"model": "micro", "micro": {"nx": 4},
               "pressure": {"P1": {"expr": "where(x2 > 1, -0.001, 0.001)"}}})  # fmt: skip
    with pytest.raises(SceneError, match=r"^pressure\.P1 = -0\.001 at x1 = \S+, x2 = 1\.5 \(cell"):
        check_used_values(s, MPI.COMM_WORLD)


def test_valid_expressions_pass_and_linear_fields_need_no_meshes(monkeypatch):
    check_used_values(scene(SMALL | {"material": {"E": {"expr": "1 + x1 * x2"}}}), MPI.COMM_WORLD)
    import plantgrowth.runner.scene_run as fc

    monkeypatch.setattr(fc, "macro_domain", None)  # would fail if called
    check_used_values(scene(SMALL | {"material": {"E": {"from": 1, "to": 2}}}), MPI.COMM_WORLD)


@pytest.mark.mpi
def test_the_cli_refuses_a_bad_interior_value_before_writing(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "bad_field")
    path = directory / "scene.toml"
    tables = SMALL | {"growth": {"law": "stress"},
                      "material": {"nu": {"expr": "where(x1 > 3, 0.6, 0.3)"}}}  # fmt: skip
    write(path, dict_to_toml(tables))
    code, _, err = call(["run", path, "-o", directory / "out"], capsys)
    assert code == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "material.nu = 0.6 at x1 = 4.6188, x2 = 0 (coarse node 2)" in err
        assert "Traceback" not in err
    assert not (directory / "out").exists()
    code, _, err = call(["validate", path], capsys)
    assert code == 2


# --- Fg0 per component, loads along their edge -------------------------------------------------


@pytest.mark.mpi
def test_Fg0_entries_may_be_fields_and_det_is_checked_where_used():
    Fg0 = [[{"expr": "1 + 0.1 * x2"}, 0], [0, {"from": 1, "to": 2}]]
    s = scene(SMALL | {"growth": {"law": "stress", "Fg0": Fg0}})
    Fg0 = s.growth.initial(np.array([0.0, REFERENCE_WIDTH]), np.array([0.0, 3.0]))
    np.testing.assert_allclose(Fg0, [[[1.0, 0.0], [0.0, 1.0]], [[1.3, 0.0], [0.0, 2.0]]])
    assert parse_scene(tomllib.loads(s.to_toml())) == s
    check_used_values(s, MPI.COMM_WORLD)
    s = scene(SMALL | {"growth": {"law": "stress", "Fg0": [[{"from": 1, "to": -1}, 0], [0, 1]]}})
    with pytest.raises(SceneError) as caught:  # both ends are fine, det < 0 past the middle
        check_used_values(s, MPI.COMM_WORLD)
    text = str(caught.value)
    assert text.startswith("growth.Fg0: det = -0.0") and "(fine cell midpoint)" in text
    assert text.endswith("is out of range: it must be finite and in (0, inf)")
    with pytest.raises(SceneError, match=r"^growth\.Fg0\[1\]\[0\]\.expr: unknown name 'y'"):
        scene({"growth": {"law": "stress", "Fg0": [[1, 0], [{"expr": "y"}, 1]]}})


def test_loads_may_vary_along_their_edge():
    s = scene({"growth": {"law": "none"},
               "loads": {"right": [{"expr": "1e-4 * s / 3"}, 0], "left": [-5e-5, 0]}})  # fmt: skip
    assert s.to_dict()["loads"]["right"] == [{"expr": "1e-4 * s / 3"}, 0.0]
    assert parse_scene(tomllib.loads(s.to_toml())) == s
    with pytest.raises(SceneError, match=r"^loads: net x1 force .*\(integrals over the edges"):
        scene({"growth": {"law": "none"}, "loads": {"right": [{"expr": "1e-4 * s"}, 0]}})
    with pytest.raises(SceneError, match=r"^loads\.top\[1\]\.expr: unknown name 'x1' at pos"):
        scene({"growth": {"law": "none"}, "loads": {"top": [0, {"expr": "x1"}]}})
    with pytest.raises(SceneError, match=r"^loads\.top\[1\] = nan at s = 0 is out of range"):
        scene({"growth": {"law": "none"}, "loads": {"top": [0, {"expr": "log(s - 1)"}]}})
    with pytest.raises(SceneError, match=r"^unknown key 'loads\.top\[1\]\.from'"):
        scene({"growth": {"law": "none"}, "loads": {"top": [0, {"from": 1, "to": 2}]}})


# --- runs ----------------------------------------------------------------------------------------

RUN = SMALL | {
    "time": {"t_max": 2, "dt": 1},
    "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
    "output": {"fields": ["u", "G"], "precision": "float64"},
}


def run(directory, name: str, tables: dict, capsys, step=2) -> tuple[list, dict[str, np.ndarray]]:
    """Run a small macro scene through the CLI: its summary rows and that step's fields."""
    merged = {k: dict(v) for k, v in RUN.items()}
    for key, entries in tables.items():
        merged.setdefault(key, {}).update(entries)
    path = directory / f"{name}.toml"
    write(path, dict_to_toml(merged))
    outdir = directory / name
    code, _, err = call(["run", path, "-o", outdir], capsys)
    assert code == 0, err
    with h5py.File(step_file(outdir, step), "r") as f:
        fields = {name: f[name][...] for name in ("u", "G")}
    return read_summary(outdir), fields


def read_summary(outdir) -> list[dict[str, float]]:
    with open(outdir / "summary.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


MEASURES = ("area", "growth_rate_11", "growth_rate_22", "u1_max", "u2_max", "det_Fg_min")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return shared_dir(tmp_path_factory, "field_runs"), {}


@pytest.mark.mpi
def test_an_expression_equal_to_linear_fields_gives_the_same_run(runs, capsys):
    """P1 along x1 (grad P1, P2 terms), E along x2, an Fg0 entry along x1 and a load, as
    numbers or {from, to} and as expressions: the same cell inputs (key_tolerance rounds them
    alike), the same forms: equal to 1e-12 (round-off of the field values, ~1e-16, amplified
    by the solves)."""
    directory, _ = runs
    W = REFERENCE_WIDTH
    linear = {"pressure": {"P1": {"from": 0.0005, "to": 0.002}},
              "material": {"E": {"from": 0.5, "to": 2.0, "along": "x2"}},
              "growth": {"law": "stress", "Fg0": [[{"from": 1.0, "to": 1.1}, 0], [0, 1]]},
              "loads": {"right": [0.0005, 0.0002], "left": [-0.0005, 0.0]}}  # fmt: skip
    expr = {"pressure": {"P1": {"expr": f"0.0005 + 0.0015 * x1 / {W!r}"}},
            "material": {"E": {"expr": "0.5 + 1.5 * x2 / 3"}},
            "growth": {"law": "stress", "Fg0": [[{"expr": f"1 + 0.1 * x1 / {W!r}"}, 0], [0, 1]]},
            "loads": {"right": [{"expr": "0.0005 + 0 * s"}, 0.0002],
                      "left": [-0.0005, 0.0]}}  # fmt: skip
    rows_a, fields_a = run(directory, "linear", linear, capsys)
    rows_b, fields_b = run(directory, "expr", expr, capsys)
    for a, b in zip(rows_a, rows_b, strict=True):
        for key in MEASURES:
            assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-300), key
    for name in ("u", "G"):
        scale = np.abs(fields_a[name]).max()
        assert scale > 0.0
        np.testing.assert_allclose(fields_b[name], fields_a[name], rtol=0, atol=1e-12 * scale)


def test_a_pressure_gradient_along_x2_grows_the_top_faster(runs, capsys):
    """P1 from 0.0005 at x2 = 0 to 0.002 at the top, stress law: the growth rate follows the
    local turgor (docs/model.md section 4: ~ (1 - phi_w)/phi_w P1), so the top cells grow ~4x faster
    than the bottom ones; the x1 direction sees no gradient (left and right halves alike)."""
    directory, _ = runs
    tables = {"pressure": {"P1": {"from": 0.0005, "to": 0.002, "along": "x2"}},
              "growth": {"law": "stress"}, "output": {"fields": ["u", "G"]}}  # fmt: skip
    _, fields = run(directory, "x2_pressure", tables, capsys)
    G = fields["G"]  # (n_cells, 9) in the written (global) cell order
    midpoints = _cell_midpoints(directory / "x2_pressure")
    trace = G[:, 0] + G[:, 4]
    top, bottom = midpoints[:, 1] > 2.5, midpoints[:, 1] < 0.5
    assert trace[top].mean() > 2.5 * trace[bottom].mean() > 0.0
    left, right = midpoints[:, 0] < REFERENCE_WIDTH / 2, midpoints[:, 0] > REFERENCE_WIDTH / 2
    assert trace[left].mean() == pytest.approx(trace[right].mean(), rel=0.05)


@pytest.mark.mpi
def test_a_load_growing_along_the_edge_stretches_the_top_more(runs, capsys):
    """Static solve (law none): f1 = +-4e-5 s / 3 on the right and left edges (balanced: equal
    and opposite; small, as E_hom ~ 2e-3) against the constant load of the same resultant
    (+-2e-5): the linear load opens the tissue more at the top and less at the bottom."""
    directory, _ = runs
    fields = {}
    for name, f in (("load_s", {"expr": "4e-5 * s / 3"}), ("load_constant", 2e-5)):
        minus = {"expr": "-4e-5 * s / 3"} if name == "load_s" else -2e-5
        tables = {"growth": {"law": "none"}, "loads": {"right": [f, 0.0], "left": [minus, 0.0]},
                  "pressure": {"P1": 0.0}}  # fmt: skip
        fields[name] = run(directory, name, tables, capsys, step=0)[1]["u"]
    with h5py.File(directory / "load_s" / "fields.h5", "r") as f:
        points = f["Mesh/geometry"][...]
    W = REFERENCE_WIDTH

    def opening(u, x2):  # u1(right) - u1(left) at height x2
        at = np.isclose(points[:, 1], x2)
        right, left = at & np.isclose(points[:, 0], W), at & np.isclose(points[:, 0], 0.0)
        return float(u[right, 0][0] - u[left, 0][0])

    s_top, s_bottom = opening(fields["load_s"], 3.0), opening(fields["load_s"], 0.0)
    c_top, c_bottom = opening(fields["load_constant"], 3.0), opening(fields["load_constant"], 0.0)
    assert s_top > c_top > 0.0 and 0.0 < s_bottom < c_bottom


def _cell_midpoints(outdir) -> np.ndarray:
    with h5py.File(outdir / "fields.h5", "r") as f:
        points, cells = f["Mesh/geometry"][...], f["Mesh/topology"][...]
    return points[cells].mean(axis=1)[:, :2]


@pytest.mark.skip_in_parallel
def test_mpirun_reproduces_the_serial_expression_run(runs, capsys):
    """``mpirun -n 2 plantgrowth run`` of the expression scene against the serial run: 1e-8
    relative, as in test_macro_run (only the macro LU and reduction order differ)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    directory, _ = runs
    if not (directory / "expr" / "summary.csv").exists():
        test_an_expression_equal_to_linear_fields_gives_the_same_run(runs, capsys)
    outdir = directory / "expr_mpirun"
    command = [mpirun, "-n", "2", PLANTGROWTH, "run", str(directory / "expr.toml"), "-o", outdir]
    done = subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=300)
    assert done.returncode == 0, done.stderr
    for a, b in zip(read_summary(directory / "expr"), read_summary(outdir), strict=True):
        for key in MEASURES:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-300), key
