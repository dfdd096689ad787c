"""Meshes are partitioned the same way in every run (plantgrowth/__init__.py: PT-SCOTCH on one
thread), so a scene run twice on the same ranks builds the same hierarchies and gives the same
numbers."""

from __future__ import annotations

import os

import numpy as np
import pytest
from mpi4py import MPI

import plantgrowth  # noqa: F401  (sets SCOTCH_PTHREAD_NUMBER before any mesh is made)
from plantgrowth.models.macro.problem import rectangle_mesh
from plantgrowth.scene import parse_scene

pytestmark = pytest.mark.mpi  # on 1 rank there is one partition; the check is the 2-rank run's


def test_scotch_runs_on_one_thread_unless_the_user_says_otherwise():
    assert os.environ["SCOTCH_PTHREAD_NUMBER"] == "1"


def test_a_mesh_made_again_is_partitioned_as_before():
    """Four makings of a 7,200-cell rectangle: each rank owns the same cells every time (with
    SCOTCH's threads, 4 makings on 2 ranks gave 4 different partitions)."""
    tissue = {"width": 6.0, "height": 3.0, "h": 0.1}
    scene = parse_scene({"tissue": tissue, "growth": {"law": "none"}})
    owned = []
    for _ in range(4):
        msh = rectangle_mesh(scene, MPI.COMM_WORLD)
        n = msh.topology.index_map(msh.topology.dim).size_local
        owned.append(np.sort(np.asarray(msh.topology.original_cell_index)[:n]))
    for again in owned[1:]:
        np.testing.assert_array_equal(again, owned[0])
