"""Growth outputs a biologist reads (issue 11, item 3): ``trG``, ``growth_anisotropy``,
``growth_direction``, ``stress_direction`` (plantgrowth/base/principal.py, growth_fields.py).

The principal-value helpers are checked on hand-made tensors; the macro fields on a homogeneous
scene, whose growth is exactly isotropic with tr G = 2 eta (1 - phi_w) P1 / phi_w (docs/model.md
section 4), and on an eta-gradient scene, whose differential growth makes it anisotropic. In-process
runs through ``main`` (serial and under mpirun); the serial-vs-``mpirun -n 2`` comparison is a
subprocess (``skip_in_parallel``). Runs: h = 0.5, H = 1, cell_resolution 1, two steps.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from cli_helpers import ENV, PLANTGROWTH, call, shared_dir, write

from plantgrowth.base import principal
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.growth_fields import GrowthFields
from plantgrowth.results.reader import read_series
from plantgrowth.scene.limits import DEFAULT_OUTPUT, GROWTH_FIELDS, OUTPUT_FIELDS

ROUND_OFF = 1e-12  # closed-form 2x2 algebra on O(1) numbers: a few ulps
FIELDS = ["u", "G", "sigma_hom", *GROWTH_FIELDS]
SCENE = """\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
eta = {eta}
[time]
t_max = 2
dt = 1
[accuracy]
cell_resolution = 1
[output]
fields = {fields}
precision = "float64"
"""


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


# --- the helpers on hand-made tensors -----------------------------------------------------------

CASES = {  # name -> (tensor, (t1, t2), anisotropy, direction)
    "diagonal": (np.diag([3.0, 1.0]), (3.0, 1.0), 0.5, (1.0, 0.0)),
    "vertical_points_up": (np.diag([1.0, 3.0]), (3.0, 1.0), 0.5, (0.0, 1.0)),
    "isotropic": (2.0 * np.eye(2), (2.0, 2.0), 0.0, (0.0, 0.0)),
    "zero": (np.zeros((2, 2)), (0.0, 0.0), 0.0, (0.0, 0.0)),
    "grow_and_shrink": (np.diag([1.0, -1.0]), (1.0, -1.0), 1.0, (1.0, 0.0)),
    "one_rate_zero": (np.diag([0.0, 2.0]), (2.0, 0.0), 1.0, (0.0, 1.0)),
    "both_negative": (np.diag([-1.0, -3.0]), (-1.0, -3.0), 0.5, (1.0, 0.0)),
    "isotropic_shrinkage": (-np.eye(2), (-1.0, -1.0), 0.0, (0.0, 0.0)),
    "rotated_30": (
        rotation(np.pi / 6) @ np.diag([2.0, 1.0]) @ rotation(np.pi / 6).T,
        (2.0, 1.0), 1.0 / 3.0, (np.cos(np.pi / 6), np.sin(np.pi / 6)),
    ),
    "rotated_120_x1_made_positive": (
        rotation(2 * np.pi / 3) @ np.diag([2.0, 1.0]) @ rotation(2 * np.pi / 3).T,
        (2.0, 1.0), 1.0 / 3.0, (np.cos(-np.pi / 3), np.sin(-np.pi / 3)),
    ),
    "symmetric_part_is_used": (np.array([[1.0, 2.0], [0.0, 1.0]]), (2.0, 0.0), 1.0,
                               (np.sqrt(0.5), np.sqrt(0.5))),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CASES))
def test_principal_values_anisotropy_and_direction_of_known_tensors(name):
    T, (t1, t2), anisotropy, direction = CASES[name]
    values = principal.principal_values(T)
    assert values == pytest.approx((t1, t2), abs=ROUND_OFF)
    assert principal.trace(T) == pytest.approx(t1 + t2, abs=ROUND_OFF)
    assert principal.anisotropy(T) == pytest.approx(anisotropy, abs=ROUND_OFF)
    assert principal.principal_direction(T) == pytest.approx(np.array(direction), abs=ROUND_OFF)


def test_helpers_agree_with_an_eigen_solver_on_random_tensors():
    """Vectorised over many tensors: values equal eigh's, the direction is eigh's eigenvector
    of the largest value up to its sign, with x1 >= 0; anisotropy in [0, 1]."""
    rng = np.random.default_rng(11)
    A = rng.normal(size=(500, 2, 2))
    T = 0.5 * (A + np.swapaxes(A, 1, 2))
    eigenvalues, eigenvectors = np.linalg.eigh(T)
    t1, t2 = principal.principal_values(T)
    assert np.allclose(t1, eigenvalues[:, 1], rtol=0, atol=ROUND_OFF)
    assert np.allclose(t2, eigenvalues[:, 0], rtol=0, atol=ROUND_OFF)
    d = principal.principal_direction(T)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=ROUND_OFF)
    assert np.allclose(np.abs(np.sum(d * eigenvectors[:, :, 1], axis=1)), 1.0, atol=1e-9)
    assert np.all(d[:, 0] >= 0.0)
    a = principal.anisotropy(T)
    assert np.all((a >= 0.0) & (a <= 1.0))
    both_positive = t2 > 0
    assert np.allclose(a[both_positive], ((t1 - t2) / (t1 + t2))[both_positive], atol=ROUND_OFF)


def test_direction_is_the_zero_vector_only_below_the_isotropy_threshold():
    base = np.eye(2)
    nearly = base + np.diag([0.5e-6, -0.5e-6]) * principal.ISOTROPIC  # anisotropy 5e-13
    clearly = base + np.diag([10.0, -10.0]) * principal.ISOTROPIC  # anisotropy 1e-5
    assert np.all(principal.principal_direction(nearly) == 0.0)
    assert principal.principal_direction(clearly) == pytest.approx(np.array([1.0, 0.0]))


def test_the_growth_outputs_are_scene_fields_and_computed_only_when_asked():
    assert set(GROWTH_FIELDS) <= set(OUTPUT_FIELDS)
    assert not set(GROWTH_FIELDS) & set(DEFAULT_OUTPUT)


# --- macro runs ---------------------------------------------------------------------------------


def run(factory, name: str, eta: str, capsys, fields=FIELDS) -> tuple:
    directory = shared_dir(factory, name)
    scene = directory / "scene.toml"
    write(scene, SCENE.format(eta=eta, fields=str(list(fields)).replace("'", '"')))
    code, _, err = call(["run", scene, "-o", directory / "out"], capsys)
    assert code == 0, err
    return scene, directory / "out"


@pytest.mark.mpi
def test_homogeneous_growth_is_isotropic_at_the_exact_rate(tmp_path_factory, capsys):
    _, outdir = run(tmp_path_factory, "homogeneous", "1.0", capsys)
    series = read_series(outdir)
    phi_w = HoneycombCell(1.0, 1.0, 30.0, 0.05).phi_w
    # tr G, docs/model.md section 4 (eta = 1, P1 = 1e-3)
    exact = 2.0 * 1.0 * (1.0 - phi_w) * 0.001 / phi_w
    for t in series.times:
        trG = series.cell_field("trG", t)
        G = series.cell_field("G", t)
        # the exact state up to the LU solve's round-off (float64 fields)
        assert trG == pytest.approx(np.full_like(trG, exact), rel=1e-9)
        assert np.array_equal(trG, G[:, 0] + G[:, 4])
        assert np.max(series.cell_field("growth_anisotropy", t)) < 1e-9
        # isotropic G and sigma_hom: no direction
        assert np.all(series.cell_field("growth_direction", t) == 0.0)
        assert np.all(series.cell_field("stress_direction", t) == 0.0)


@pytest.mark.mpi
def test_gradient_growth_is_anisotropic_with_unit_directions(tmp_path_factory, capsys):
    """eta from 0.5 to 2: by t = 2 the differential growth has built anisotropic stresses."""
    _, outdir = run(tmp_path_factory, "gradient", "{from = 0.5, to = 2.0}", capsys)
    series = read_series(outdir)
    t = series.times[-1]
    G = series.cell_field("G", t)[:, [0, 1, 3, 4]].reshape(-1, 2, 2)
    anisotropy = series.cell_field("growth_anisotropy", t)
    assert np.max(anisotropy) > 1e3 * principal.ISOTROPIC  # measured 2.2e-3
    assert anisotropy == pytest.approx(principal.anisotropy(G), abs=ROUND_OFF)
    for name in ("growth_direction", "stress_direction"):
        direction = series.cell_field(name, t)
        assert direction.shape == (len(series.triangles), 3) and np.all(direction[:, 2] == 0.0)
        norms = np.linalg.norm(direction[:, :2], axis=1)
        assert np.all((np.abs(norms - 1.0) < ROUND_OFF) | (norms == 0.0))
        assert np.all(direction[:, 0] >= 0.0)
    assert np.all(np.linalg.norm(series.cell_field("growth_direction", t), axis=1) > 0.5)
    assert series.cell_field("growth_direction", t)[:, :2] == pytest.approx(
        principal.principal_direction(G), abs=ROUND_OFF
    )


def test_a_scene_that_does_not_ask_writes_and_computes_none(tmp_path_factory, capsys):
    _, outdir = run(tmp_path_factory, "default", "1.0", capsys, fields=DEFAULT_OUTPUT)
    assert not set(GROWTH_FIELDS) & set(read_series(outdir).names)
    assert GrowthFields(None, DEFAULT_OUTPUT).functions == {}  # no function, no space, no work


@pytest.mark.skip_in_parallel
def test_mpirun_writes_the_serial_growth_fields(tmp_path_factory, capsys):
    """Same scene on 2 ranks: canonical cell order, so the arrays match to the solves'
    round-off: 1e-8 relative for the scalars (measured ~1e-13); a direction's round-off is G's
    divided by g1 - g2, here down to 5e-5 of tr G, so unit vectors get 1e-8 absolute (measured
    2.7e-12)."""
    scene, serial = run(tmp_path_factory, "serial", "{from = 0.5, to = 2.0}", capsys)
    parallel = serial.parent / "mpi"
    done = subprocess.run(
        ["mpirun", "-n", "2", PLANTGROWTH, "run", str(scene), "-o", str(parallel)],
        env=ENV, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    a, b = read_series(serial), read_series(parallel)
    assert a.times == b.times
    for name in GROWTH_FIELDS:
        for t in a.times:
            absolute = 1e-8 if name.endswith("_direction") else 1e-12
            assert b.cell_field(name, t) == pytest.approx(
                a.cell_field(name, t), rel=1e-8, abs=absolute
            ), name
