FROM debian:bookworm

COPY . /opt/plantgrowth
WORKDIR /opt/plantgrowth

RUN bash scripts/install.sh && rm -rf /var/lib/apt/lists/*

# Open MPI refuses to run as root without these (e.g. `mpirun -n 2 plantgrowth ...`).
ENV OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    OMPI_MCA_btl_vader_single_copy_mechanism=none

# The main job: the reference scene (docs/model.md section 9), outputs under /opt/plantgrowth/results.
CMD ["plantgrowth", "run", "scenes/reference_stress.toml", "-o", "results/reference_stress"]
