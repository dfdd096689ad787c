"""gmsh geometry: the periodic unit cell, the cellular tissue and its outline."""
