#!/usr/bin/env bash
# The one install script of plantgrowth (used by README, .ci/run and the Dockerfile).
#
# Idempotent. On a bare Debian bookworm, run as root, it:
#   1. apt-installs the Debian packages that provide dolfinx, gmsh, h5py, PETSc, MPI, ...
#      (only if some are missing; no `apt-get update` otherwise);
#   2. creates the venv .venv at the repo root from /usr/bin/python3 with
#      --system-site-packages (so the Debian builds are seen; NEVER pip-install
#      dolfinx, gmsh, h5py, petsc4py, mpi4py, numpy or scipy into it);
#   3. pip-installs this repo in editable mode plus the dev tools into .venv;
#      then compiles its bytecode (editable installs are not compiled by pip) and installs
#      the Jupyter kernel "plantgrowth" (.venv's python) for docs/tutorial.ipynb;
#   4. as root, links /usr/local/bin/plantgrowth -> .venv/bin/plantgrowth.
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"

RUFF_VERSION="0.6.9"
# meshio: an independent XDMF reader the tests check our time series with (pure Python;
# its numpy requirement is met by Debian's numpy, so pip installs no numpy wheel).
MESHIO_VERSION="5.3.5"

APT_PACKAGES=(
    python3-dolfinx
    python3-dolfinx-mpc
    python3-gmsh
    python3-h5py
    python3-h5py-mpi  # under mpirun, h5py loads this MPI build (the runs write without MPI-IO)
    python3-petsc4py
    python3-mpi4py
    python3-pytest
    python3-pytest-xdist  # scripts/test.sh runs the serial phase on one worker per core
    python3-matplotlib
    python3-scipy
    python3-yaml      # tests/test_citation.py reads CITATION.cff
    python3-nbformat  # docs/tutorial.ipynb: tests/test_tutorial.py and
    python3-nbclient  # scripts/figures/render_tutorial.py run it in a kernel
    python3-ipykernel # of .venv's python (the kernelspec "plantgrowth", step 3c)
    python3-skimage   # [tissue] cells = "labels.tif": imported label images (issue 34,
    python3-tifffile  # docs/real_tissues.md) are read with tifffile (TIFF) or skimage.io (PNG),
    python3-shapely   # checked with skimage.measure and their walls simplified with shapely
    libdeflate0       # the step files' deflate streams (plantgrowth/base/deflate.py)
    libopenblas0-serial  # numpy's, scipy's and PETSc's BLAS/LAPACK (Debian's alternatives pick
                      # it over the reference BLAS; serial: one thread per MPI rank):
                      # docs/large_tissues.md, "An optimized BLAS"
    python3-venv
    python3-pip
    git
    openmpi-bin
)

# Optional: PLANTGROWTH_WITH_PARAVIEW=1 also installs ParaView (pvbatch), whose own XDMF reader
# tests/test_paraview_reader.py then uses on a run's output (large; not needed otherwise), and
# a virtual X server: pvbatch aborts without a display, so headless it runs as
# `xvfb-run -a pvbatch ...` (xauth: xvfb-run needs it, and it is only a recommendation of xvfb).
if [[ "${PLANTGROWTH_WITH_PARAVIEW:-0}" == "1" ]]; then
    APT_PACKAGES+=(paraview python3-paraview xvfb xauth)
fi

log() { echo "[install.sh] $*"; }

# --- 1. Debian packages -------------------------------------------------------
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
    status="$(dpkg-query -W -f='${db:Status-Status}' "$pkg" 2>/dev/null || true)"
    if [[ "$status" != "installed" ]]; then
        missing+=("$pkg")
    fi
done
if ((${#missing[@]} > 0)); then
    if [[ "$(id -u)" -ne 0 ]]; then
        echo "[install.sh] missing Debian packages: ${missing[*]}" >&2
        echo "[install.sh] run this script as root (or apt-get install them yourself)." >&2
        exit 1
    fi
    log "installing Debian packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q
    # --no-install-recommends is enough: gcc/g++ and python3-dev (needed by the
    # ffcx JIT) and openssh-client (mpirun) are hard dependencies.
    apt-get install -y -q --no-install-recommends "${APT_PACKAGES[@]}"
else
    log "Debian packages already installed"
fi

# --- 2. venv --------------------------------------------------------------------
VENV="$REPO/.venv"
if [[ -x "$VENV/bin/python" ]] && "$VENV/bin/python" -c 'import sys' >/dev/null 2>&1 \
    && grep -qi '^include-system-site-packages *= *true' "$VENV/pyvenv.cfg" 2>/dev/null; then
    log "venv .venv already present"
else
    log "creating venv .venv (with system site packages)"
    rm -rf "$VENV"
    /usr/bin/python3 -m venv --system-site-packages "$VENV"
fi

# --- 3. editable install + dev tools ---------------------------------------------
# Re-run pip only if pyproject.toml changed since the last successful install
# (or the console script / ruff are missing).
export PIP_DISABLE_PIP_VERSION_CHECK=1
STAMP="$VENV/.plantgrowth-install-stamp"
want_stamp="$(sha256sum pyproject.toml | cut -d' ' -f1) ruff==$RUFF_VERSION meshio==$MESHIO_VERSION"
if [[ -f "$STAMP" && "$(cat "$STAMP")" == "$want_stamp" && -x "$VENV/bin/plantgrowth" \
    && -x "$VENV/bin/ruff" ]]; then
    log "plantgrowth (editable) and ruff already installed in .venv"
else
    log "pip install -e ., ruff==$RUFF_VERSION and meshio==$MESHIO_VERSION into .venv"
    # --no-build-isolation: build with Debian's setuptools (>= 64, PEP 660 editable)
    # instead of downloading one.
    "$VENV/bin/python" -m pip install --quiet --no-build-isolation --no-deps -e .
    "$VENV/bin/python" -m pip install --quiet "ruff==$RUFF_VERSION" "meshio==$MESHIO_VERSION"
    echo "$want_stamp" >"$STAMP"
fi

# --- 3b. bytecode -------------------------------------------------------------------
# pip does not compile an editable install, and with PYTHONDONTWRITEBYTECODE set (as in many
# containers and CI machines) Python would compile plantgrowth's sources afresh in every
# process: about 0.1-0.2 s of each command's start-up (docs/large_tissues.md, "Start-up").
# Writing the __pycache__ files here is idempotent; a source edited later is recompiled in
# memory (Python checks the source's time stamp), never run stale.
"$VENV/bin/python" -m compileall -q plantgrowth forms meshes
log "compiled plantgrowth's bytecode"

# --- 3c. Jupyter kernel --------------------------------------------------------------
# docs/tutorial.ipynb runs in the kernelspec "plantgrowth": .venv's python, which imports this
# repository (Debian's own "python3" kernel runs /usr/bin/python3, which does not). Installed
# into .venv/share/jupyter/kernels, where Jupyter started from .venv finds it. The debugger's
# warning about frozen modules (debugpy, at every kernel start) is silenced.
KERNEL="$VENV/share/jupyter/kernels/plantgrowth/kernel.json"
if [[ -f "$KERNEL" ]] && grep -q "\"$VENV/bin/python\"" "$KERNEL"; then
    log "Jupyter kernel plantgrowth already installed in .venv"
else
    PYDEVD_DISABLE_FILE_VALIDATION=1 "$VENV/bin/python" -Xfrozen_modules=off -m ipykernel \
        install --sys-prefix --name plantgrowth --display-name "Python (plantgrowth)" \
        --env PYDEVD_DISABLE_FILE_VALIDATION 1 >/dev/null
    log "installed the Jupyter kernel plantgrowth (.venv's python)"
fi

# --- 4. CLI on PATH ---------------------------------------------------------------
if [[ "$(id -u)" -eq 0 ]]; then
    ln -sfn "$VENV/bin/plantgrowth" /usr/local/bin/plantgrowth
    log "linked /usr/local/bin/plantgrowth -> $VENV/bin/plantgrowth"
else
    log "not root: use $VENV/bin/plantgrowth or 'source .venv/bin/activate'"
fi
log "done"
