"""``plantgrowth export`` and ``Results.field_table`` (issue 32, item 6): a written field as a CSV
table, one row per triangle (DG0) or node (P1) and written time, that reads back to exactly what
``pg.read_results`` returns; its named errors; it never writes into the run nor over a file
without --overwrite.

In-process through ``main`` (serial and under mpirun: rank 0 writes, every rank returns the same
code and reads the table back). The run: macro, h = 0.5, two steps, output every step.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from cli_helpers import RANK0, call, runs_and_pictures

import plantgrowth as pg

MACRO = """\
[tissue]
h = 0.5
H = 1.0
[growth]
law = "stress"
eta = {from = 0.5, to = 2.0}
[time]
t_max = 2
[accuracy]
cell_resolution = 1
[output]
fields = ["u", "G", "E_hom", "trG", "growth_direction"]
"""
TIMES = [0.0, 1.0, 2.0]  # the run's written times (t_max = 2, dt = 1, every step written)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """(the run's directory, an empty directory for the tables)."""
    dirs, tables = runs_and_pictures(tmp_path_factory, "export", {"macro": MACRO})
    return dirs["macro"], tables


def read_csv(path) -> dict[str, np.ndarray]:
    """The CSV file's columns by header name, parsed as float64 (Python's float of each text)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float)
    return {name: body[:, i] for i, name in enumerate(header)}


def expected(results: pg.Results, name: str, t: float) -> dict[str, np.ndarray]:
    """The columns of ``name`` at ``t`` built from pg.read_results' arrays, independently of
    plantgrowth.results.field_table."""
    values = results.field(name, t)
    x0, tri, u = results.points, results.triangles, results.field("u", t)
    on_nodes = name == "u"
    place = x0 if on_nodes else x0[tri].mean(axis=1)
    moved = x0 + u if on_nodes else (x0 + u)[tri].mean(axis=1)
    row = np.flatnonzero(np.isclose(results.summary["t"], t, rtol=1e-12, atol=0.0))[0]
    step = results.summary["step"][row]
    columns = {"step": np.full(len(place), step), "t": np.full(len(place), t),
               "node" if on_nodes else "triangle": np.arange(len(place)),
               "x1": place[:, 0], "x2": place[:, 1],
               "x1_deformed": moved[:, 0], "x2_deformed": moved[:, 1]}  # fmt: skip
    if values.ndim == 3:
        columns |= {f"{name}_{i}{j}": values[:, i - 1, j - 1] for i in (1, 2) for j in (1, 2)}
    elif values.ndim == 2:
        columns |= {f"{name}_{i}": values[:, i - 1] for i in (1, 2)}
    else:
        columns[name] = values
    return columns


@pytest.mark.parametrize(
    "name, time",
    [("G", "1"), ("G", "all"), ("u", None), ("u", "all"), ("E1111", "0"),
     ("growth_direction", "2")],
)  # fmt: skip
def test_export_round_trips_against_read_results(run, name, time, capsys):
    """DG0 (G, a tensor; growth_direction, a vector; E1111, coarse-node values interpolated to
    the triangles) and P1 (u), at one time and at all. Exact: the CSV holds each float64 in its
    shortest round-trip form (repr), so the text reads back to the same number."""
    directory, tables = run
    output = tables / f"{name}_{time}.csv"
    argv = ["export", directory, "--field", name, "-o", output]
    code, out, err = call([*argv, *(["--time", time] if time else [])], capsys)
    assert code == 0, err
    assert (f"wrote {output}" in out) == RANK0
    table = read_csv(output)
    results = pg.read_results(directory)
    times = TIMES if time == "all" else [TIMES[-1] if time is None else float(time)]
    parts = [expected(results, name, t) for t in times]
    want = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    assert list(table) == list(want)
    for key in want:
        np.testing.assert_array_equal(table[key], want[key], err_msg=key)
    api = results.field_table(name, time if time in (None, "all") else float(time))
    assert list(api) == list(want) and all(np.array_equal(api[k], table[k]) for k in want)


def test_export_replaces_a_file_only_with_overwrite(run, capsys):
    directory, tables = run
    output = tables / "replaced.csv"
    if RANK0:
        output.write_text("a user's file\n")
    code, _, err = call(["export", directory, "--field", "trG", "-o", output], capsys)
    assert code == 2
    if RANK0:
        assert "--overwrite" in err and output.read_text() == "a user's file\n"
    code, _, err = call(["export", directory, "--field", "trG", "-o", output, "--overwrite"],
                        capsys)  # fmt: skip
    assert code == 0, err
    assert read_csv(output)["trG"].shape == (len(pg.read_results(directory).triangles),)
    assert not list(tables.glob(".*"))  # no temporary file left


ERRORS = {  # argv after "export"; fragments of the one-line message
    "unknown_field": (["{run}", "--field", "Gg", "-o", "{out}"],
                      ["'Gg'", "written: E1111", "G, growth_direction, trG, u"]),
    "time_not_written": (["{run}", "--field", "G", "--time", "1.5", "-o", "{out}"],
                         ["t = 1.5", "written times: 0, 1, 2"]),
    "time_malformed": (["{run}", "--field", "G", "--time", "last", "-o", "{out}"], ["--time"]),
    "no_dir": (["{tables}/nothing", "--field", "G", "-o", "{out}"], ["no such directory"]),
    "not_a_run": (["{tables}", "--field", "G", "-o", "{run}.csv"],
                  ["no summary.csv", "not a plantgrowth run directory"]),
    "missing_parent": (["{run}", "--field", "G", "-o", "{tables}/no/such/G.csv"],
                       ["-o", "does not exist"]),
    "inside_run": (["{run}", "--field", "G", "-o", "{run}/G.csv"], ["inside the run directory"]),
    "not_csv": (["{run}", "--field", "G", "-o", "{tables}/G.txt"], ["-o", ".csv"]),
    "no_field": (["{run}", "-o", "{out}"], ["--field"]),
}  # fmt: skip


@pytest.mark.parametrize("case", ERRORS, ids=list(ERRORS))
def test_export_names_what_is_wrong_and_writes_nothing(run, case, capsys):
    directory, tables = run
    argv, fragments = ERRORS[case]
    places = {"{run}": str(directory), "{tables}": str(tables), "{out}": str(tables / "x.csv")}
    for key, value in places.items():
        argv = [a.replace(key, value) for a in argv]
    everything = directory.parent  # the run, the tables and beside them
    before = sorted(everything.rglob("*")) if RANK0 else None
    code, out, err = call(["export", *argv], capsys)
    assert code == 2
    if RANK0:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: "), err
        assert all(f in lines[0] for f in fragments), lines[0]
        assert sorted(everything.rglob("*")) == before
    else:
        assert err == "" and out == ""


def test_field_table_refuses_a_time_that_is_not_a_number(run):
    with pytest.raises(pg.InputError, match="time = 'last' is invalid"):
        pg.read_results(run[0]).field_table("G", "last")
