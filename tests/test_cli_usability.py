"""The command line tells the user what to do (issue 8, section 3, "CLI"): the commands with no
arguments, a description per command, a quiet end when stdout is closed, a failure printed once
(naming ranks only under MPI), compare progress and table that say what they are, and scene
messages that say how to fix the input.

In-process tests call ``main`` on every rank (so they also run under mpirun; rank 0 alone
prints); the subprocess ones are ``skip_in_parallel``.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import tomllib

import pytest
from cli_helpers import ENV, PLANTGROWTH, RANK0, call, shared_dir, write
from mpi4py import MPI

from plantgrowth.cli import build_parser
from plantgrowth.scene import SceneError, parse_scene

COMMANDS = ("cell", "run", "compare", "validate", "sweep", "render", "export")
SMALL = (
    '[tissue]\nh = 0.5\n[growth]\nlaw = "stress"\n{growth}[time]\nt_max = {t_max}\n'
    "[accuracy]\ncell_resolution = 1\n"
)
INVERTING = SMALL.format(growth="Fg0 = [[4, 0], [0, 1]]\n", t_max=2)
"""Pre-grown 4:1: every element inverts at step 0 (the hard case anisotropic_Fg0_x1)."""


@pytest.mark.mpi
def test_no_arguments_lists_the_commands(capsys):
    code, out, err = call([], capsys)
    assert code == 2
    if RANK0:
        assert all(command in out for command in COMMANDS), out
        assert err.startswith("plantgrowth: error: no command given") and len(err.splitlines()) == 1


@pytest.mark.skip_in_parallel
def test_the_bare_command_lists_the_commands():
    done = subprocess.run([PLANTGROWTH], capture_output=True, text=True, env=ENV, timeout=60)
    assert done.returncode == 2
    assert all(command in done.stdout for command in COMMANDS), done.stdout
    assert "Traceback" not in done.stderr and len(done.stderr.splitlines()) == 1


def test_every_command_has_a_description():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert sorted(sub.choices) == sorted(COMMANDS)
    for name, command in sub.choices.items():
        assert command.description and len(command.description) > 30, name
        helps = {a.dest: a.help for a in sub._choices_actions}
        assert helps.get(name), f"{name} has no one-line help in the command list"


@pytest.mark.skip_in_parallel
def test_piping_the_progress_into_head_ends_quietly(tmp_path):
    """``plantgrowth run ... | head -1``: the reader goes away after one line. Today PETSc's
    SIGPIPE handler aborted MPI (exit 59, "Broken Pipe"); the run must finish its outputs and
    exit 0 without a word on stderr."""
    scene, outdir = tmp_path / "scene.toml", tmp_path / "out"
    scene.write_text(SMALL.format(growth="", t_max=20))
    proc = subprocess.Popen(
        [PLANTGROWTH, "run", str(scene), "-o", str(outdir)], env=ENV,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    first = proc.stdout.readline()
    proc.stdout.close()  # what head does after its line
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 0, err
    assert first.startswith("plantgrowth run ")
    assert err == ""
    with open(outdir / "summary.csv", newline="") as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == list(range(21))


@pytest.mark.mpi
def test_a_failure_is_printed_once_and_names_ranks_only_under_mpi(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "failure")
    scene = directory / "inverting.toml"
    write(scene, INVERTING)
    code, out, err = call(["run", scene, "-o", directory / "out"], capsys)
    assert code == 3
    if RANK0:
        assert (out + err).count("run failed") == 1 and "element inverted" not in out, out + err
        assert (
            err.startswith("plantgrowth: run failed: step 0, t = 0: ")
            and len(err.splitlines()) == 1
        ), err
        assert "on this rank" not in err
        if MPI.COMM_WORLD.size == 1:
            assert "rank" not in err
        else:
            assert " on rank 0" in err and " on rank 1" in err
        assert "run failed" in (directory / "out" / "run.log").read_text()


def test_compare_errors_at_t_max_are_the_first_steps_without_growth(tmp_path_factory, capsys):
    """No growth (stress law, threshold tau = 1 far above the wall stress; law "none" would run
    t = 0 only): the state at t_max is the state at t = 0, so each ``_tmax`` error
    equals its first-step value (to the round-off of repeated identical LU solves, 1e-12);
    a t_max error left unmeasured, or computed from other fields than the first step's, fails."""
    directory = shared_dir(tmp_path_factory, "compare_tmax")
    scene, outdir = directory / "scene.toml", directory / "cmp"
    write(scene, '[tissue]\nh = 0.5\n[growth]\nlaw = "stress"\ntau = 1.0\n[time]\nt_max = 2\n'
                 "[accuracy]\ncell_resolution = 1\n[micro]\nnx = 2\nresolution = 1\n")  # fmt: skip
    code, _, err = call(["compare", scene, "--nx", "2", "-o", outdir], capsys)
    assert code == 0, err
    if not RANK0:
        return
    with open(outdir / "compare.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    for key in ("err_u1", "err_u2", "err_ubar", "err_G"):
        assert float(row[f"{key}_tmax"]) == pytest.approx(float(row[key]), rel=1e-12, abs=1e-14)
    assert float(row["err_u2"]) > 0.0


@pytest.mark.mpi
def test_compare_says_which_model_and_nx_and_leaves_t_max_empty(tmp_path_factory, capsys):
    """Progress lines name the model and Nx; the errors are labelled relative; with
    --first-step-only the t_max columns are empty instead of repeating t = 0."""
    directory = shared_dir(tmp_path_factory, "compare")
    scene, outdir = directory / "scene.toml", directory / "cmp"
    write(scene, SMALL.format(growth="", t_max=1) + "[micro]\nnx = 2\nresolution = 1\n")
    code, out, err = call(
        ["compare", scene, "--nx", "2", "--first-step-only", "-o", outdir], capsys
    )
    assert code == 0, err
    if not RANK0:
        return
    step_lines = [line for line in out.splitlines() if "step 0/0" in line]
    assert [line.split(": step")[0] for line in step_lines] == ["Nx = 2, macro", "Nx = 2, micro"]
    assert "Nx = 2, step 0, relative errors: err_u1 = " in out
    with open(outdir / "compare.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    assert row["rate_macro_tmax"] == row["rate_micro_tmax"] == ""
    assert {row[f"{key}_tmax"] for key in ("err_u1", "err_u2", "err_ubar", "err_G")} == {""}
    assert float(row["rate_macro_t0"]) > 0.0 and float(row["rate_micro_t0"]) > 0.0


def _error(text: str) -> str:
    with pytest.raises(SceneError) as caught:
        parse_scene(tomllib.loads(text))
    return str(caught.value)


@pytest.mark.parametrize(
    "time_table, fix",
    [
        ("t_max = 10.5\ndt = 1", "use time.t_max = 10 or 11, or a time.dt that divides it"),
        ("t_max = 1\ndt = 0.3", "use time.t_max = 0.9 or 1.2, or a time.dt that divides it"),
        ("t_max = 0.5\ndt = 1", "set time.t_max to a multiple of time.dt"),
    ],
)
def test_the_t_max_dt_message_says_how_to_fix_it(time_table, fix):
    message = _error(f'[growth]\nlaw = "stress"\n[time]\n{time_table}\n')
    assert message.startswith("time.t_max") and fix in message, message


@pytest.mark.parametrize(
    "text, suggestion",
    [
        ("[cell]\nnu = 0.3\n", "did you mean 'material.nu'?"),
        ("[material]\ntheta = 30\n", "did you mean 'cell.theta'?"),
        ("dt = 0.5\n", "did you mean 'time.dt'?"),
        ("[tissue]\nnx = 8\n", "did you mean 'micro.nx'?"),
        ("[material]\nnuu = 0.3\n", "did you mean 'nu'?"),  # a typo in the right table
    ],
)
def test_a_key_in_the_wrong_table_is_pointed_to_its_table(text, suggestion):
    message = _error(text + '[growth]\nlaw = "stress"\n')
    assert message.startswith("unknown key ") and suggestion in message, message
