"""Reading what a run wrote (serial, h5py, no dolfinx) and drawing it (``plantgrowth render``).

May import: ``plantgrowth.base`` only, so reading and drawing need neither dolfinx nor MPI.
"""
