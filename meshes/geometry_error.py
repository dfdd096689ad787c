"""The error of an impossible cell geometry, in a module of its own (no numpy), so that the CLI's
error handling loads nothing heavy (``plantgrowth --help``)."""


class GeometryError(ValueError):
    """An impossible cell geometry; the message names the parameter and its valid range."""
