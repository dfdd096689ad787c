"""plantgrowth: multiscale simulation of plant tissue growth (see README.md)."""
